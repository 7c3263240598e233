//! Builds the book as HTML to read it locally: `cargo run --release --example build_book [DIR]`
//! (default `out/book`), then open DIR/index.html. The same build runs inside `cargo test`
//! (`tests/repository/book.rs`), which also checks includes, anchors, images and links.

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root.join("out/book"));
    let mut book = match mdbook_driver::MDBook::load(root.join("book")) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("the book does not load: {e}");
            std::process::exit(1);
        }
    };
    book.config.build.build_dir = out.clone();
    if let Err(e) = book.build() {
        eprintln!("the book does not build: {e}");
        std::process::exit(1);
    }
    let index = if out.join("html/index.html").exists() {
        out.join("html/index.html")
    } else {
        out.join("index.html")
    };
    println!("{}", index.display());
}
