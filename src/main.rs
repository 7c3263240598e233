use clap::Parser;

fn main() {
    let cli = pathspace::cli::Cli::parse();
    if let Err(e) = pathspace::cli::run(cli) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
