//! `bench`: the host tool for a board on a bench. See `hil_sim::bench::cli` (and
//! `bench --help`).

fn main() -> std::process::ExitCode {
    hil_sim::bench::cli::main()
}
