//! The `texsyn` command line: a thin layer over the library (see `cli/mod.rs`).

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
