use std::process::ExitCode;

fn main() -> ExitCode {
    graybox::cli::main()
}
