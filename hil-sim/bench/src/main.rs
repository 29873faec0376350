//! `bench`: the host tool for a board on a bench. See `bench::cli` (and
//! `bench --help`).

fn main() -> std::process::ExitCode {
    bench::cli::main()
}
