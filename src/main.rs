use clap::Parser;

mod source_tree {
    include!(concat!(env!("OUT_DIR"), "/source_tree.rs"));
}

fn main() {
    // `pathspace info scene.toml | head` must end quietly, not panic on a closed pipe
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = pathspace::cli::Cli::parse();
    match pathspace::cli::run_with_source(cli, source_tree::SOURCE_TREE) {
        Ok(()) => {}
        // a render a signal stopped: what was written, and the status a shell gives the signal
        Err(pathspace::cli::CliError::Interrupted { signal, what }) => {
            eprintln!("{}", pathspace::cli::printable(&what));
            std::process::exit(128 + signal);
        }
        Err(e) => {
            eprintln!("error: {}", pathspace::cli::printable(&e.to_string()));
            std::process::exit(1);
        }
    }
}
