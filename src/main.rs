use clap::Parser;

fn main() {
    // `pathspace info scene.toml | head` must end quietly, not panic on a closed pipe
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = pathspace::cli::Cli::parse();
    if let Err(e) = pathspace::cli::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
