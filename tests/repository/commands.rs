//! The commands the README and the book show are commands the CLI takes: every `pathspace ...`
//! line (also written `cargo run --release -- ...`, `./target/release/pathspace ...` or `$P ...`
//! with `P=target/release/pathspace`), in code blocks and in inline code, is parsed by the
//! command line's own parser. A renamed flag or subcommand turns this red before a reader finds
//! the stale command.

use crate::common;

use clap::{CommandFactory, Parser};
use common::docs::{commands, documents, is_synopsis, words};
use pathspace::cli::Cli;

#[test]
fn every_command_in_the_readme_and_the_book_parses() {
    let subcommands: Vec<String> = Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    let (mut checked, mut failures) = (0, Vec::new());
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for (line, args) in commands(&text) {
            let Some(words) = words(&args) else { continue };
            // prose that merely names the program ("pathspace is ...") is no command
            let Some(sub) = words.first() else { continue };
            if is_synopsis(&words) {
                continue;
            }
            if !subcommands.contains(sub) && !sub.starts_with('-') {
                continue;
            }
            checked += 1;
            let argv = std::iter::once("pathspace".to_string()).chain(words);
            let parsed = Cli::try_parse_from(argv)
                .map(|_| ())
                .or_else(|e| match e.kind() {
                    clap::error::ErrorKind::DisplayHelp
                    | clap::error::ErrorKind::DisplayVersion => Ok(()),
                    _ => Err(e),
                });
            if let Err(e) = parsed {
                let first = e.to_string().lines().next().unwrap_or_default().to_string();
                failures.push(format!("{}:{line}: `{args}`: {first}", doc.display()));
            }
        }
    }
    eprintln!("{checked} commands checked");
    assert!(
        checked >= 60,
        "only {checked} commands found: the extraction broke"
    );
    assert!(
        failures.is_empty(),
        "{} commands do not parse:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
