//! The `railgrip` binary: parses arguments, calls the library, prints, maps errors to exit
//! codes (0 ok, 1 error, 2 usage, 3 completed but some input was skipped or lost).

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
