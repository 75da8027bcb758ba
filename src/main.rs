//! The `coupler-atlas` command line: parse flags, build a validated job, run it, map
//! errors to a message and an exit code. The work lives in the library.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
