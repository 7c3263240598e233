//! The book as a course: the registry of assignments and the student copy of the crate
//! (book: "Course use: assignments").
//!
//! An assignment is a region of a function body marked in the source by a line
//! `// ASSIGNMENT: name` and a line `// END ASSIGNMENT`; the signature and the doc comment stay,
//! the body is what the student writes. One assignment may mark several bodies (a sampler and
//! its pdf). The registry, data beside the book (`book/course.toml`, [`Registry`]), names for
//! each the chapter that derives it, the files that hold its regions and the tests that grade
//! it (by module path), with the syllabus's hours, prerequisites and expected picture; `tests/assignments.rs` checks that the markers and
//! the registry agree, that a copy with every region blanked compiles, that each assignment's
//! graded tests fail there on its own `todo!()`, and that no line of a removed region survives
//! anywhere in the copy (the book includes code by anchor, so it shows the `todo!()` too).

pub mod assignment;
pub mod exercise;
mod fsx;
pub mod identity;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where the registry lives in a crate's tree: data beside the book.
pub const REGISTRY_FILE: &str = "book/course.toml";

/// One graded test, addressed by its module path `TARGET::PATH::FUNCTION`: the test target
/// under `tests/` and the function's path inside it, so that
/// `cargo test --release --test TARGET -- --exact PATH::FUNCTION` runs exactly it.
#[derive(Clone, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(try_from = "String")]
pub struct GradedTest {
    /// The test target (`tests/TARGET.rs` or `tests/TARGET/main.rs`).
    pub target: String,
    /// The test function's path inside its target (`module::function`, or `function`).
    pub path: String,
}

impl TryFrom<String> for GradedTest {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        let (target, path) = s
            .split_once("::")
            .ok_or_else(|| format!("graded test `{s}` is not TARGET::PATH::FUNCTION"))?;
        let ident =
            |p: &str| !p.is_empty() && p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ident(target) || !path.split("::").all(ident) {
            return Err(format!("graded test `{s}` is not a module path"));
        }
        Ok(GradedTest {
            target: target.to_string(),
            path: path.to_string(),
        })
    }
}

impl std::fmt::Display for GradedTest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}::{}", self.target, self.path)
    }
}

impl GradedTest {
    /// The command that runs this test alone in a copy.
    pub fn command(&self) -> String {
        format!(
            "cargo test --release --test {} -- --exact {}",
            self.target, self.path
        )
    }

    /// The test function's name (the last segment of its path).
    pub fn function(&self) -> &str {
        self.path.rsplit("::").next().unwrap_or(&self.path)
    }

    /// The files, relative to the crate, that may hold the function: its module's file in the
    /// two layouts Cargo and rustc accept (`m.rs` or `m/mod.rs`, and a target's `main.rs`).
    pub fn module_files(&self) -> Vec<String> {
        let mut dirs = vec![format!("tests/{}", self.target)];
        let mut files = vec![
            format!("tests/{}.rs", self.target),
            format!("tests/{}/main.rs", self.target),
        ];
        let segments: Vec<&str> = self.path.split("::").collect();
        for m in &segments[..segments.len() - 1] {
            let mut next_dirs = Vec::new();
            files.clear();
            for d in &dirs {
                files.push(format!("{d}/{m}.rs"));
                files.push(format!("{d}/{m}/mod.rs"));
                next_dirs.push(format!("{d}/{m}"));
            }
            dirs = next_dirs;
        }
        files
    }
}

/// An assignment: a marked region (or several) that a student copy replaces by `todo!()`.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Assignment {
    /// The name after `// ASSIGNMENT:`.
    pub name: String,
    /// The chapter's title, as in `book/src/SUMMARY.md`.
    pub chapter: String,
    /// The chapter's file under `book/src/`.
    pub chapter_file: String,
    /// The source files holding the marked regions.
    pub files: Vec<String>,
    /// What the student writes, in one line.
    pub task: String,
    /// The tests that grade it: they pass on the original and fail while the region is blank.
    pub tests: Vec<GradedTest>,
    /// A student's time for it, in hours (the syllabus).
    pub hours: u32,
    /// Assignments to do first (each earlier in the registry).
    #[serde(default)]
    pub prerequisites: Vec<String>,
    /// What the student should see once it works: an image under `book/src/`.
    pub picture: String,
}

/// The course: every assignment and measurement exercise, in the order of the syllabus.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Registry {
    #[serde(rename = "assignment")]
    pub assignments: Vec<Assignment>,
    #[serde(rename = "exercise", default)]
    pub exercises: Vec<exercise::Exercise>,
}

impl Registry {
    /// Reads the registry's text (`book/course.toml`).
    pub fn parse(text: &str) -> Result<Self, CourseError> {
        toml::from_str(text).map_err(|e| CourseError::RegistryFile(e.to_string()))
    }

    /// The registry a tree carries.
    pub fn of_tree(tree: &Tree) -> Result<Self, CourseError> {
        let bytes = tree
            .get(REGISTRY_FILE)
            .ok_or_else(|| CourseError::RegistryFile(format!("no {REGISTRY_FILE}")))?;
        Self::parse(&String::from_utf8_lossy(bytes))
    }

    /// The registry of the crate in `root`.
    pub fn read(root: &Path) -> Result<Self, CourseError> {
        let p = root.join(REGISTRY_FILE);
        let text = std::fs::read_to_string(&p)
            .map_err(|e| CourseError::Read(p.display().to_string(), e))?;
        Self::parse(&text)
    }

    /// The assignment called `name`.
    pub fn find(&self, name: &str) -> Option<&Assignment> {
        self.assignments.iter().find(|a| a.name == name)
    }
}

/// The marker that opens a region.
pub const BEGIN: &str = "// ASSIGNMENT:";
/// The marker that closes a region.
pub const END: &str = "// END ASSIGNMENT";

/// A marked region of one file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Region {
    pub name: String,
    /// 1-based line of the `// ASSIGNMENT:` marker.
    pub begin: usize,
    /// 1-based line of the `// END ASSIGNMENT` marker.
    pub end: usize,
    /// The lines strictly between the markers.
    pub body: Vec<String>,
}

/// A malformed assignment marker in a source text (the line numbers are 1-based).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MarkerError {
    /// A region opened inside another (the line, the open region's name and first line).
    #[error("line {0}: `{begin}` inside assignment `{1}` opened on line {2}", begin = BEGIN)]
    Nested(usize, String, usize),
    /// An opening marker without a name.
    #[error("line {0}: `{begin}` without a name", begin = BEGIN)]
    NoName(usize),
    /// A closing marker without a region open.
    #[error("line {0}: `{end}` without `{begin}`", end = END, begin = BEGIN)]
    EndWithoutBegin(usize),
    /// A region still open at the end of the text (its name, its first line).
    #[error("assignment `{0}` opened on line {1} is never closed by `{end}`", end = END)]
    Unclosed(String, usize),
}

/// Why a course tree cannot be read, checked, blanked or written; the messages are what
/// `pathspace assignment` prints.
#[derive(Debug, thiserror::Error)]
pub enum CourseError {
    /// A malformed marker in a file (its path, the marker's fault).
    #[error("{0}: {1}")]
    Marker(String, #[source] MarkerError),
    /// The registry and the markers disagree: every problem, one a line.
    #[error("{}", .0.join("\n"))]
    Registry(Vec<String>),
    /// A file with assignments that is not UTF-8.
    #[error("{0} is not UTF-8")]
    NotUtf8(String),
    /// A directory without a crate.
    #[error("{0} holds no Cargo.toml")]
    NoCargoToml(String),
    /// The copy's target holds files already.
    #[error("{0} exists and is not empty; choose a new directory")]
    NotEmpty(String),
    /// A file that cannot be read (its path, the cause).
    #[error("cannot read {0}: {1}")]
    Read(String, #[source] std::io::Error),
    /// A directory that cannot be created (its path, the cause).
    #[error("cannot create {0}: {1}")]
    Create(String, #[source] std::io::Error),
    /// A file that cannot be written (its path, the cause).
    #[error("cannot write {0}: {1}")]
    Write(String, #[source] std::io::Error),
    /// The copy's identity cannot be written ([`identity`]; why).
    #[error("cannot give the copy its identity: {0}")]
    Identity(String),
    /// A directory that cannot be listed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The copy's target is no directory or cannot be written (its path, why).
    #[error("{0}: {1}")]
    Output(String, String),
    /// The registry file cannot be read as a registry (why).
    #[error("{REGISTRY_FILE}: {0}")]
    RegistryFile(String),
}

impl From<CourseError> for String {
    fn from(e: CourseError) -> Self {
        e.to_string()
    }
}

impl From<MarkerError> for String {
    fn from(e: MarkerError) -> Self {
        e.to_string()
    }
}

/// The marked regions of a source text, or a description of a malformed marker.
pub fn regions(text: &str) -> Result<Vec<Region>, MarkerError> {
    let mut out = Vec::new();
    let mut open: Option<Region> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix(BEGIN) {
            if let Some(r) = &open {
                return Err(MarkerError::Nested(i + 1, r.name.clone(), r.begin));
            }
            let name = rest.split_whitespace().next().unwrap_or("").to_string();
            if name.is_empty() {
                return Err(MarkerError::NoName(i + 1));
            }
            open = Some(Region {
                name,
                begin: i + 1,
                end: 0,
                body: Vec::new(),
            });
        } else if trimmed.starts_with(END) {
            let Some(mut r) = open.take() else {
                return Err(MarkerError::EndWithoutBegin(i + 1));
            };
            r.end = i + 1;
            out.push(r);
        } else if let Some(r) = open.as_mut() {
            r.body.push(line.to_string());
        }
    }
    if let Some(r) = open {
        return Err(MarkerError::Unclosed(r.name, r.begin));
    }
    Ok(out)
}

/// The `todo!()` a student copy has in place of the region of `a`.
pub fn todo_line(a: &Assignment) -> String {
    format!(
        "todo!(\"assignment {}: see book chapter '{}', book/src/{}\")",
        a.name, a.chapter, a.chapter_file
    )
}

/// `text` with the regions of the chosen assignments replaced by their `todo!()` (the marker
/// lines stay, so the student sees where to write), and the removed lines.
pub fn blank(text: &str, chosen: &[&Assignment]) -> Result<(String, Vec<String>), MarkerError> {
    regions(text)?; // reject malformed markers first
    let mut out = String::with_capacity(text.len());
    let mut removed = Vec::new();
    let mut skipping: Option<&Assignment> = None;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix(BEGIN) {
            let name = rest.split_whitespace().next().unwrap_or("");
            out.push_str(line);
            if let Some(a) = chosen.iter().find(|a| a.name == name) {
                let indent = &line[..line.len() - trimmed.len()];
                out.push_str(&format!("{indent}{}\n", todo_line(a)));
                skipping = Some(a);
            }
        } else if trimmed.starts_with(END) {
            skipping = None;
            out.push_str(line);
        } else if skipping.is_some() {
            removed.push(line.trim_end_matches(['\n', '\r']).to_string());
        } else {
            out.push_str(line);
        }
    }
    Ok((out, removed))
}

/// A removed line counts as solution text when it says something: at least this many
/// non-blank characters. Shorter lines (`} else {`, `return 0.0;`, `let k = x.len() - 1;`)
/// are the common words of any Rust function and occur elsewhere in the crate by nature.
pub const SOLUTION_LINE_MIN_CHARS: usize = 24;

/// True when `line` is long enough to count as solution text.
pub fn is_solution_text(line: &str) -> bool {
    line.chars().filter(|c| !c.is_whitespace()).count() >= SOLUTION_LINE_MIN_CHARS
}

/// The crate's files as (relative path, bytes).
pub type Tree = BTreeMap<String, Vec<u8>>;

/// Files of the source tree that a student copy leaves out: the teacher's own test, which
/// makes and grades copies.
pub fn excluded_from_copy(path: &str) -> bool {
    path == "tests/assignments.rs"
}

include!("tree.rs");

/// Reads a crate's source tree from a directory (the same selection as `build.rs` embeds).
pub fn read_tree(root: &Path) -> Result<Tree, CourseError> {
    fn walk(root: &Path, dir: &Path, out: &mut Tree) -> Result<(), CourseError> {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Ok(());
        };
        for e in entries {
            let p = e?.path();
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            let name = rel.rsplit('/').next().unwrap_or("");
            if rel.starts_with("book/book/")
                || rel.split('/').any(|part| part == "target")
                || rel.ends_with(".snap.new")
                || rel.ends_with(".pending-snap")
                || name.starts_with('.')
            {
                continue;
            }
            if p.is_dir() {
                walk(root, &p, out)?;
            } else {
                let bytes =
                    std::fs::read(&p).map_err(|e| CourseError::Read(p.display().to_string(), e))?;
                out.insert(rel, bytes);
            }
        }
        Ok(())
    }
    if !root.join("Cargo.toml").is_file() {
        return Err(CourseError::NoCargoToml(root.display().to_string()));
    }
    let mut tree = Tree::new();
    for f in FILES {
        if let Ok(b) = std::fs::read(root.join(f)) {
            tree.insert(f.to_string(), b);
        }
    }
    let members = workspace_members(&std::fs::read_to_string(root.join("Cargo.toml"))?);
    for d in DIRS.iter().map(|d| d.to_string()).chain(members) {
        walk(root, &root.join(d), &mut tree)?;
    }
    Ok(tree)
}

/// Every marked region under `src/` of a tree: (file, region).
pub fn markers(tree: &Tree) -> Result<Vec<(String, Region)>, CourseError> {
    let mut out = Vec::new();
    for (path, bytes) in tree {
        if !(path.starts_with("src/") && path.ends_with(".rs")) {
            continue;
        }
        let Ok(text) = std::str::from_utf8(bytes) else {
            continue;
        };
        for r in regions(text).map_err(|e| CourseError::Marker(path.clone(), e))? {
            out.push((path.clone(), r));
        }
    }
    Ok(out)
}

/// Checks that the markers of `tree` and its registry agree: every marker is registered
/// (with its file), every assignment has at least one region, and only in its listed files;
/// every prerequisite comes earlier and every picture exists. Returns the registry.
pub fn check_registry(tree: &Tree) -> Result<Registry, CourseError> {
    let registry = Registry::of_tree(tree)?;
    let marks = markers(tree)?;
    let mut problems = Vec::new();
    for (file, r) in &marks {
        match registry.find(&r.name) {
            None => problems.push(format!(
                "{file}:{}: assignment `{}` is not in the registry ({REGISTRY_FILE})",
                r.begin, r.name
            )),
            Some(a) if !a.files.contains(file) => problems.push(format!(
                "{file}:{}: assignment `{}` is marked here but the registry lists {:?}",
                r.begin, r.name, a.files
            )),
            _ => {}
        }
        if r.body.iter().all(|l| l.trim().is_empty()) {
            problems.push(format!(
                "{file}:{}: assignment `{}` is empty",
                r.begin, r.name
            ));
        }
    }
    for (i, a) in registry.assignments.iter().enumerate() {
        for p in &a.prerequisites {
            if !registry.assignments[..i].iter().any(|b| &b.name == p) {
                problems.push(format!(
                    "assignment `{}`: prerequisite `{p}` is no earlier assignment",
                    a.name
                ));
            }
        }
        if !tree.contains_key(&format!("book/src/{}", a.picture)) {
            problems.push(format!(
                "assignment `{}`: picture book/src/{} does not exist",
                a.name, a.picture
            ));
        }
        for f in &a.files {
            if !marks.iter().any(|(file, r)| file == f && r.name == a.name) {
                problems.push(format!(
                    "assignment `{}`: no `{BEGIN} {}` marker in {f}",
                    a.name, a.name
                ));
            }
        }
        if a.tests.is_empty() {
            problems.push(format!("assignment `{}` has no graded test", a.name));
        }
        if !tree.contains_key(&format!("book/src/{}", a.chapter_file)) {
            problems.push(format!(
                "assignment `{}`: chapter book/src/{} does not exist",
                a.name, a.chapter_file
            ));
        }
    }
    let mut names: Vec<&str> = registry
        .assignments
        .iter()
        .map(|a| a.name.as_str())
        .collect();
    names.sort();
    names.dedup();
    if names.len() != registry.assignments.len() {
        problems.push("two assignments share a name".to_string());
    }
    if problems.is_empty() {
        Ok(registry)
    } else {
        Err(CourseError::Registry(problems))
    }
}

/// A student copy in memory: the tree with the chosen regions blanked, and the removed lines.
pub struct StudentCopy {
    pub tree: Tree,
    pub removed: Vec<(String, Vec<String>)>,
    /// Code lines (not comments) of the original's `src/` outside every marked region: the
    /// crate's shared idioms (`let d2 = d.length_squared();`, an exponential step), which a
    /// removed line may repeat without giving the solution away.
    pub shared: std::collections::BTreeSet<String>,
}

/// The trimmed code lines of `src/**/*.rs` outside every marked region.
fn shared_code_lines(tree: &Tree) -> std::collections::BTreeSet<String> {
    let mut out = std::collections::BTreeSet::new();
    for (path, bytes) in tree {
        if !(path.starts_with("src/") && path.ends_with(".rs")) {
            continue;
        }
        let Ok(text) = std::str::from_utf8(bytes) else {
            continue;
        };
        let mut inside = false;
        for line in text.lines() {
            let l = line.trim();
            if l.starts_with(BEGIN) {
                inside = true;
            } else if l.starts_with(END) {
                inside = false;
            } else if !inside && !l.starts_with("//") {
                out.insert(l.to_string());
            }
        }
    }
    out
}

/// Blanks the regions of `chosen` in `tree` (leaving out [`excluded_from_copy`] files).
pub fn student_copy(tree: &Tree, chosen: &[&Assignment]) -> Result<StudentCopy, CourseError> {
    check_registry(tree)?;
    let mut out = Tree::new();
    let mut removed: Vec<(String, Vec<String>)> = chosen
        .iter()
        .map(|a| (a.name.to_string(), Vec::new()))
        .collect();
    for (path, bytes) in tree {
        if excluded_from_copy(path) {
            continue;
        }
        let touched: Vec<&Assignment> = chosen
            .iter()
            .copied()
            .filter(|a| a.files.contains(path))
            .collect();
        if touched.is_empty() {
            out.insert(path.clone(), bytes.clone());
            continue;
        }
        let text = std::str::from_utf8(bytes).map_err(|_| CourseError::NotUtf8(path.clone()))?;
        for a in &touched {
            let (_, lines) = blank(text, &[a]).map_err(|e| CourseError::Marker(path.clone(), e))?;
            let slot = removed.iter_mut().find(|(n, _)| *n == a.name).unwrap();
            slot.1.extend(lines);
        }
        let (blanked, _) =
            blank(text, &touched).map_err(|e| CourseError::Marker(path.clone(), e))?;
        out.insert(path.clone(), blanked.into_bytes());
    }
    Ok(StudentCopy {
        tree: out,
        removed,
        shared: shared_code_lines(tree),
    })
}

/// Where solution text survives in a copy: (assignment, file, line number, the line). A
/// removed line is solution text when it is long enough ([`is_solution_text`]) and is not one
/// of the crate's shared code lines; it is searched in every file of the copy (sources, tests,
/// the book's markdown, examples, comments included).
pub fn leaks(copy: &StudentCopy) -> Vec<(String, String, usize, String)> {
    let mut out = Vec::new();
    for (name, lines) in &copy.removed {
        let needles: Vec<&str> = lines
            .iter()
            .map(|l| l.trim())
            .filter(|l| is_solution_text(l) && !copy.shared.contains(*l))
            .collect();
        for (path, bytes) in &copy.tree {
            let Ok(text) = std::str::from_utf8(bytes) else {
                continue;
            };
            for (i, line) in text.lines().enumerate() {
                if let Some(n) = needles.iter().find(|n| line.contains(**n)) {
                    out.push((name.clone(), path.clone(), i + 1, n.to_string()));
                }
            }
        }
    }
    out
}

/// Checks, before the copy is made, that `out` can take it: a new or empty directory (created
/// here) that can be written, not a file.
pub fn check_copy_target(out: &Path) -> Result<(), CourseError> {
    if out.is_dir() && std::fs::read_dir(out)?.next().is_some() {
        return Err(CourseError::NotEmpty(out.display().to_string()));
    }
    fsx::check_output_dir(out)
}

/// Writes a student copy to `out` (which must not exist or be empty).
pub fn write_copy(copy: &StudentCopy, out: &Path) -> Result<(), CourseError> {
    if out.exists() && std::fs::read_dir(out)?.next().is_some() {
        return Err(CourseError::NotEmpty(out.display().to_string()));
    }
    for (path, bytes) in &copy.tree {
        let p: PathBuf = out.join(path);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| CourseError::Create(parent.display().to_string(), e))?;
        }
        std::fs::write(&p, bytes).map_err(|e| CourseError::Write(p.display().to_string(), e))?;
    }
    Ok(())
}
