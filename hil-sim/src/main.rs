//! `hil-sim`: see `hil_sim::cli` (and `hil-sim --help`).

fn main() -> std::process::ExitCode {
    hil_sim::cli::main()
}
