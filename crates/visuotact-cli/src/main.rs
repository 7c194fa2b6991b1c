//! The `visuotact` binary: everything lives in the library's `run`.

fn main() -> std::process::ExitCode {
    visuotact_cli::run()
}
