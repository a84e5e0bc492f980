//! The `nimbus` command line. All the work is in the library (`nimbus::cli`).

fn main() -> std::process::ExitCode {
    nimbus::cli::main()
}
