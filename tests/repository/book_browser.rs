//! The book in a real browser, offline: the book is built, and every chapter is served from
//! 127.0.0.1 and opened in headless Chromium, whose every request goes through this test's server
//! (it is Chromium's proxy too, loopback included). A chapter passes when no request left the
//! book (another host, or `CONNECT` for https; the few hosts Chromium calls on its own are logged
//! and set apart, see `CHROMIUM_OWN_HOSTS`), none failed (404), no raw TeX delimiter is left in
//! its text outside code, MathJax reported no TeX error, and it shows at least as many rendered
//! formulas (`mjx-container`) as its markdown writes.
//!
//! Needs `/usr/bin/chromium` (or `chromium` on `PATH`, or the binary `PATHSPACE_CHROMIUM` names;
//! `.ci/run` installs it). Without it the test is skipped with a notice on the terminal, and
//! `tests/z_not_checked.rs` repeats the notice at the end of the suite; with
//! `PATHSPACE_REQUIRE_BROWSER=1` (`.ci/run` sets it) a missing Chromium fails the test.

use crate::common::browser;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn book_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("book")
}

/// A fresh directory under the system's temporary directory.
fn temp_dir(what: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "pathspace-{what}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// ---------------------------------------------------------------------------------------------
// The server: the book's files on 127.0.0.1, and Chromium's proxy.

/// Hosts that Chromium itself calls, whatever the page: Debian's wrapper (`/etc/chromium.d`)
/// turns on remote extensions (their updater) and Google API keys (account sign-in), which no
/// flag turns off; Debian's Chromium 148 also connects to www.google.com and, now and then,
/// android.clients.google.com with these flags on a page that names no host at all, so every
/// host under google.com counts as its own (a book page would load fonts or scripts from
/// googleapis.com or gstatic.com, which stay foreign). Their requests are answered 403 and
/// logged, but are not the page's.
const CHROMIUM_OWN_HOSTS: [&str; 1] = ["update.googleapis.com"];

/// Whether `host` is one Chromium calls on its own ([`CHROMIUM_OWN_HOSTS`], or under google.com).
fn chromium_own_host(host: &str) -> bool {
    CHROMIUM_OWN_HOSTS.contains(&host) || host == "google.com" || host.ends_with(".google.com")
}

/// The host a proxy request names: `CONNECT host:port` or `GET http://host[:port]/...`.
fn request_host(method: &str, target: &str) -> String {
    let authority = if method == "CONNECT" {
        target
    } else {
        let rest = target.split_once("://").map_or(target, |(_, r)| r);
        rest.split('/').next().unwrap_or("")
    };
    authority
        .rsplit_once(':')
        .map_or(authority, |(h, _)| h)
        .to_string()
}

/// One request as the server saw it.
#[derive(Clone, Debug)]
struct Request {
    line: String,
    status: u16,
    /// The request was for another host (or a `CONNECT` tunnel).
    foreign: bool,
    /// ... one of Chromium's own ([`CHROMIUM_OWN_HOSTS`]).
    chromium_own: bool,
}

struct Server {
    port: u16,
    log: Arc<Mutex<Vec<Request>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Serves `root`; every request is logged on stderr with `label` and its status.
    fn start(root: PathBuf, label: String) -> Server {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let log = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (log2, stop2) = (log.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            for stream in listener.incoming() {
                if stop2.load(Ordering::SeqCst) {
                    break;
                }
                let Ok(stream) = stream else { continue };
                let (root, log, label) = (root.clone(), log2.clone(), label.clone());
                std::thread::spawn(move || serve(stream, &root, port, &label, &log));
            }
        });
        Server {
            port,
            log,
            stop,
            thread: Some(thread),
        }
    }

    fn requests(&self) -> Vec<Request> {
        self.log.lock().unwrap().clone()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        let _ = TcpStream::connect(("127.0.0.1", self.port)); // wake the accept loop
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Serves one connection's requests (keep-alive) until the client closes it.
fn serve(stream: TcpStream, root: &Path, port: u16, label: &str, log: &Mutex<Vec<Request>>) {
    let _ = stream.set_read_timeout(Some(Duration::from_secs(30)));
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut out = stream;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let line = line.trim_end().to_string();
        if line.is_empty() {
            continue;
        }
        let mut content_length = 0usize;
        loop {
            let mut h = String::new();
            if reader.read_line(&mut h).unwrap_or(0) == 0 {
                return;
            }
            let h = h.trim_end();
            if h.is_empty() {
                break;
            }
            if let Some((k, v)) = h.split_once(':') {
                if k.eq_ignore_ascii_case("content-length") {
                    content_length = v.trim().parse().unwrap_or(0);
                }
            }
        }
        if content_length > 0 {
            let mut body = vec![0; content_length];
            let _ = reader.read_exact(&mut body);
        }
        let mut parts = line.split_whitespace();
        let method = parts.next().unwrap_or("").to_string();
        let target = parts.next().unwrap_or("").to_string();
        let own = format!("http://127.0.0.1:{port}");
        let (status, foreign, body, mime): (u16, bool, Vec<u8>, &str) = if method == "CONNECT" {
            (
                403,
                true,
                b"no tunnels out of the book\n".to_vec(),
                "text/plain",
            )
        } else if target.starts_with('/') || target.starts_with(&format!("{own}/")) {
            let path = target.strip_prefix(&own).unwrap_or(&target);
            match file_for(root, path) {
                Some((bytes, mime)) => (200, false, bytes, mime),
                None => (404, false, b"not found\n".to_vec(), "text/plain"),
            }
        } else {
            (403, true, b"not the book's host\n".to_vec(), "text/plain")
        };
        let chromium_own = foreign && chromium_own_host(&request_host(&method, &target));
        let note = if chromium_own {
            " (Chromium's own)"
        } else {
            ""
        };
        eprintln!("[{label}] {line} -> {status}{note}");
        log.lock().unwrap().push(Request {
            line: line.clone(),
            status,
            foreign,
            chromium_own,
        });
        let reason = match status {
            200 => "OK",
            403 => "Forbidden",
            _ => "Not Found",
        };
        let close = foreign;
        let head = format!(
            "HTTP/1.1 {status} {reason}\r\nContent-Type: {mime}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n{}\r\n",
            body.len(),
            if close { "Connection: close\r\n" } else { "" }
        );
        if out.write_all(head.as_bytes()).is_err() || out.write_all(&body).is_err() {
            return;
        }
        if close {
            let _ = out.shutdown(Shutdown::Both);
            return;
        }
    }
}

/// The file a request path names under `root`, with its MIME type; `None` if there is none.
fn file_for(root: &Path, path: &str) -> Option<(Vec<u8>, &'static str)> {
    let path = path.split(['?', '#']).next().unwrap();
    let path = percent_decode(path)?;
    if path.split('/').any(|c| c == "..") {
        return None;
    }
    let mut file = root.join(path.trim_start_matches('/'));
    if file.is_dir() {
        file = file.join("index.html");
    }
    let bytes = std::fs::read(&file).ok()?;
    let mime = match file.extension().and_then(|e| e.to_str()).unwrap_or("") {
        "html" => "text/html; charset=utf-8",
        "js" => "text/javascript",
        "css" => "text/css",
        "json" => "application/json",
        "svg" => "image/svg+xml",
        "png" => "image/png",
        "woff" => "font/woff",
        "woff2" => "font/woff2",
        "ttf" => "font/ttf",
        _ => "application/octet-stream",
    };
    Some((bytes, mime))
}

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

// ---------------------------------------------------------------------------------------------
// The chapters' formulas, counted in their markdown.

/// The formulas a chapter's markdown writes: `\\( ... \\)`, `\\[ ... \\]` and `$$ ... $$` outside
/// fenced code and inline code spans.
fn formulas_in_markdown(text: &str) -> usize {
    let mut prose = String::new();
    let mut fenced = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("```") || t.starts_with("~~~") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            prose.push_str(&strip_code_spans(line));
            prose.push('\n');
        }
    }
    let mut n = 0;
    for (open, close) in [("\\\\(", "\\\\)"), ("\\\\[", "\\\\]"), ("$$", "$$")] {
        let mut rest = prose.as_str();
        while let Some(a) = rest.find(open) {
            let after = &rest[a + open.len()..];
            let Some(b) = after.find(close) else { break };
            n += 1;
            rest = &after[b + close.len()..];
        }
    }
    n
}

/// A line without its inline code spans (a run of backticks up to the same run).
fn strip_code_spans(line: &str) -> String {
    let mut out = String::new();
    let mut rest = line;
    while let Some(a) = rest.find('`') {
        out.push_str(&rest[..a]);
        let run = rest[a..].chars().take_while(|&c| c == '`').count();
        let ticks = "`".repeat(run);
        let after = &rest[a + run..];
        match after.find(&ticks) {
            Some(b) => rest = &after[b + run..],
            None => {
                out.push_str(&rest[a..]);
                return out;
            }
        }
    }
    out.push_str(rest);
    out
}

// ---------------------------------------------------------------------------------------------
// The rendered page.

/// The page's HTML without the contents of the elements where TeX may legitimately remain or
/// that are not text: code, scripts, styles, and MathJax's own output.
fn text_outside_code(html: &str) -> String {
    let mut s = html.to_string();
    for tag in ["script", "style", "pre", "code", "mjx-container"] {
        let open = format!("<{tag}");
        let close = format!("</{tag}>");
        let mut out = String::new();
        let mut rest = s.as_str();
        while let Some(a) = rest.find(&open) {
            out.push_str(&rest[..a]);
            // nesting of the same tag (mjx-container in mjx-container) does not occur
            match rest[a..].find(&close) {
                Some(b) => rest = &rest[a + b + close.len()..],
                None => {
                    rest = "";
                }
            }
        }
        out.push_str(rest);
        s = out;
    }
    s
}

/// What is wrong with one chapter in the browser; empty if nothing.
fn check_chapter(
    chrome: &Path,
    root: &Path,
    page: &str,
    formulas: usize,
    budget_ms: u32,
) -> (Vec<String>, Duration) {
    let server = Server::start(root.to_path_buf(), page.to_string());
    let profile = temp_dir("chromium-profile");
    let dom_file = profile.join("dom.html");
    let err_file = profile.join("stderr.txt");
    let url = format!("http://127.0.0.1:{}/{page}", server.port);
    let started = Instant::now();
    let mut child = Command::new(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-dev-shm-usage",
            // Chromium's own traffic (not the page's), which would otherwise reach the proxy
            "--disable-default-apps",
            "--disable-extensions",
            "--disable-domain-reliability",
            "--disable-client-side-phishing-detection",
            "--no-pings",
            "--metrics-recording-only",
            "--disable-features=NetworkTimeServiceQuerying,OptimizationHints,MediaRouter,\
             Translate,AutofillServerCommunication,CertificateTransparencyComponentUpdater,\
             DialMediaRouteProvider,AccountConsistency,PrivacySandboxSettings4",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--proxy-server=http://127.0.0.1:{}", server.port))
        .arg("--proxy-bypass-list=<-loopback>")
        .arg(format!("--virtual-time-budget={budget_ms}"))
        .arg("--dump-dom")
        .arg(&url)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&dom_file).unwrap())
        .stderr(std::fs::File::create(&err_file).unwrap())
        .spawn()
        .expect("chromium starts");
    let mut problems = Vec::new();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            if !status.success() {
                problems.push(format!("chromium exited with {status}"));
            }
            break;
        }
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            problems.push("chromium did not finish within 60 s".to_string());
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let took = started.elapsed();
    let dom = std::fs::read_to_string(&dom_file).unwrap_or_default();
    let requests = server.requests();
    drop(server);

    for r in &requests {
        if r.chromium_own {
            continue;
        }
        if r.foreign {
            problems.push(format!(
                "request outside the book: {} -> {}",
                r.line, r.status
            ));
        } else if r.status != 200 {
            problems.push(format!("failed load: {} -> {}", r.line, r.status));
        }
    }
    if dom.trim().is_empty() {
        problems.push("no DOM dumped".to_string());
    } else {
        let text = text_outside_code(&dom);
        for raw in ["\\(", "\\)", "\\[", "\\]", "$$"] {
            if let Some(i) = text.find(raw) {
                let mut s = i.saturating_sub(60);
                while !text.is_char_boundary(s) {
                    s -= 1;
                }
                let mut e = (i + 60).min(text.len());
                while !text.is_char_boundary(e) {
                    e += 1;
                }
                problems.push(format!(
                    "raw TeX `{raw}` left in the text ({} times), e.g. …{}…",
                    text.matches(raw).count(),
                    text[s..e].replace('\n', " ")
                ));
            }
        }
        let rendered = dom.matches("<mjx-container").count();
        if rendered < formulas {
            problems.push(format!(
                "{rendered} rendered formulas (mjx-container), the markdown writes {formulas}"
            ));
        }
        // mdBook's smart punctuation makes a prime `'` a `’`; the config gives TeX its prime back
        if dom.contains("mjx-c2019") {
            problems.push("a typographic apostrophe (’) in a formula instead of a prime".into());
        }
        for part in dom.split("data-mjx-error=\"").skip(1) {
            let msg = part.split('"').next().unwrap_or("");
            problems.push(format!("TeX error: {msg}"));
        }
    }
    if !problems.is_empty() {
        let err = std::fs::read_to_string(&err_file).unwrap_or_default();
        // without the noise of a machine with no D-Bus
        let tail: Vec<&str> = err
            .lines()
            .filter(|l| !l.contains("dbus"))
            .rev()
            .take(5)
            .collect();
        if !tail.is_empty() {
            problems.push(format!(
                "chromium's stderr (last lines):\n      {}",
                tail.into_iter().rev().collect::<Vec<_>>().join("\n      ")
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&profile);
    (problems, took)
}

#[test]
fn every_chapter_renders_its_math_offline_in_chromium() {
    let Some(chrome) = browser::chromium() else {
        assert!(
            !browser::required(),
            "\n\n*** {} ***\n",
            browser::NOT_CHECKED
        );
        // straight to the terminal: the test harness would hide a passing test's output
        let _ = writeln!(std::io::stderr(), "\n*** {} ***\n", browser::NOT_CHECKED);
        return;
    };

    let out = temp_dir("book-browser");
    let mut book = mdbook_driver::MDBook::load(book_dir()).expect("book.toml and SUMMARY.md load");
    book.config.build.build_dir = out.clone();
    book.build().expect("the book builds");
    let root = if out.join("html/index.html").exists() {
        out.join("html")
    } else {
        out.clone()
    };

    // every chapter (each markdown file of the book), with its formulas
    let mut pages: Vec<(String, usize)> = Vec::new();
    let mut total = 0;
    let mut entries: Vec<PathBuf> = std::fs::read_dir(book_dir().join("src"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .filter(|p| p.file_name().unwrap() != "SUMMARY.md")
        .collect();
    entries.sort();
    for md in entries {
        let n = formulas_in_markdown(&std::fs::read_to_string(&md).unwrap());
        total += n;
        let html = md.with_extension("html");
        let page = html.file_name().unwrap().to_string_lossy().to_string();
        assert!(root.join(&page).exists(), "{page} was not built");
        pages.push((page, n));
    }
    assert!(total > 500, "only {total} formulas counted in the book");
    // print.html (every chapter again on one page) is left out: it would double the test's time
    // and checks nothing the chapters do not.

    let started = Instant::now();
    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    // Chromium keeps a core busy while it typesets: one browser per core
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(2)
        .clamp(2, 8);
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some((page, n)) = pages.get(i) else { break };
                let (problems, took) = check_chapter(&chrome, &root, page, *n, 5_000);
                results
                    .lock()
                    .unwrap()
                    .push((page.clone(), *n, problems, took));
            });
        }
    });
    let mut results = results.into_inner().unwrap();
    results.sort_by(|a, b| a.0.cmp(&b.0));
    let mut failed = Vec::new();
    for (page, n, problems, took) in &results {
        eprintln!(
            "{page:28} {n:5} formulas  {:5.2} s  {}",
            took.as_secs_f64(),
            if problems.is_empty() { "ok" } else { "FAILED" }
        );
        if !problems.is_empty() {
            failed.push(format!("{page}:\n  - {}", problems.join("\n  - ")));
        }
    }
    eprintln!(
        "{} pages, {total} formulas, {:.1} s with {workers} browsers at a time",
        results.len(),
        started.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&out);
    assert!(
        failed.is_empty(),
        "the book does not render offline:\n{}",
        failed.join("\n")
    );
}
