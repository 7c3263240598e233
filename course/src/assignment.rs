//! `pathspace assignment list | make | check | exercise`: the book as a course (book: "Course
//! use: assignments"). The registry and the blanking live in the crate's root.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use clap::{Args, Subcommand};

use crate::{self as course, exercise, identity, Assignment, CourseError, Registry, Tree};

/// Leaked lines listed by `make` before it gives up.
const MAX_LEAKS_SHOWN: usize = 40;

#[derive(Args, Debug)]
pub struct AssignmentArgs {
    #[command(subcommand)]
    pub command: AssignmentCommand,
}

#[derive(Subcommand, Debug)]
pub enum AssignmentCommand {
    /// List the syllabus: assignments (name, chapter, hours, prerequisites, graded tests) and
    /// measurement exercises.
    List,
    /// Write a student copy of the crate with the named assignments' bodies replaced by todo!().
    Make(MakeArgs),
    /// Run a copy's graded tests and print a pass/fail table to grade from.
    Check(CheckArgs),
    /// Grade a measurement exercise from the `converge` studies that answer it.
    Exercise(ExerciseArgs),
}

#[derive(Args, Debug)]
pub struct ExerciseArgs {
    /// The exercise (see `pathspace assignment list`).
    pub name: String,
    /// The studies' output directories (`converge -o DIR`) [default: those of the exercise's
    /// own commands].
    pub studies: Vec<PathBuf>,
}

#[derive(Args, Debug)]
pub struct MakeArgs {
    /// Assignments to blank (see `pathspace assignment list`).
    pub names: Vec<String>,
    /// Blank every assignment (a copy for a whole course).
    #[arg(long, conflicts_with = "names")]
    pub all: bool,
    /// Directory to write the copy to (must not exist or be empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Take the crate from this directory [default: the source tree embedded in the binary
    /// (feature `embed-source`), else the directory the binary was built from].
    #[arg(long)]
    pub from: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// The student's copy (a crate written by `assignment make`).
    pub dir: PathBuf,
    /// Grade only this assignment (builds only its graded tests).
    #[arg(long, conflicts_with = "all")]
    pub only: Option<String>,
    /// Grade every assignment of the registry [default: the ones the copy was made with].
    #[arg(long)]
    pub all: bool,
    /// Cargo's target directory for the copy (default: DIR/target). One per copy: copies of
    /// the crate get the same artifact names, and Cargo judges freshness by modification times,
    /// so a shared directory could grade one student's build for another's (refused).
    #[arg(long)]
    pub target_dir: Option<PathBuf>,
    /// Cargo's build directory (dependencies and the copy's intermediate artifacts), shared
    /// safely by every copy `assignment make` wrote, since each carries its own id in its
    /// version [default: the target directory of the crate this binary was built from, when
    /// it exists, so the dependencies it compiled are not compiled again; else Cargo's own].
    #[arg(long)]
    pub build_dir: Option<PathBuf>,
    /// Optimization level of the copy's own crate (dependencies keep the release profile):
    /// 0 compiles fastest (a student's edit is graded in seconds, the slowest graded test
    /// takes about 10 s), 3 runs fastest.
    #[arg(long, default_value_t = 0)]
    pub opt_level: u8,
}

/// Runs `pathspace assignment`: `embedded` is the source tree the binary carries (empty
/// without the feature `embed-source`), `built_from` the crate it was built from.
pub fn run(
    args: AssignmentArgs,
    embedded: &[(&str, &[u8])],
    built_from: &Path,
) -> Result<(), AssignmentError> {
    match args.command {
        AssignmentCommand::List => list(&source_tree(None, embedded, built_from)?),
        AssignmentCommand::Make(a) => {
            let tree = source_tree(a.from.as_deref(), embedded, built_from)?;
            make(a, tree)
        }
        AssignmentCommand::Check(a) => check(a, built_from),
        AssignmentCommand::Exercise(a) => {
            grade_exercise(a, &source_tree(None, embedded, built_from)?)
        }
    }
}

/// The tree `make` copies and `list` reads: `--from`, else the embedded tree, else the crate
/// the binary was built from.
fn source_tree(
    from: Option<&Path>,
    embedded: &[(&str, &[u8])],
    built_from: &Path,
) -> Result<Tree, AssignmentError> {
    Ok(match from {
        Some(dir) => course::read_tree(dir)?,
        None if embedded.is_empty() => course::read_tree(built_from)
            .map_err(|e| AssignmentError::NoSourceTree(e, built_from.display().to_string()))?,
        None => embedded
            .iter()
            .map(|(p, b)| (p.to_string(), b.to_vec()))
            .collect(),
    })
}

/// Why `pathspace assignment make` or `check` stops; the messages are what the command prints.
#[derive(Debug, thiserror::Error)]
pub enum AssignmentError {
    /// The tree cannot be read, checked, blanked or written.
    #[error(transparent)]
    Course(#[from] CourseError),
    /// No `--from` and no embedded tree, and the crate the binary was built from is gone (the
    /// cause, that crate's directory).
    #[error(
        "{0}: the binary was built from {1} and carries no source tree \
         (feature `embed-source`); pass --from CRATE_DIR"
    )]
    NoSourceTree(#[source] CourseError, String),
    /// `make` without a name and without `--all`.
    #[error("name at least one assignment (or --all); `pathspace assignment list` shows them")]
    NoName,
    /// `make` with a name that is no assignment.
    #[error("no assignment `{0}`; `pathspace assignment list` shows them")]
    Unknown(String),
    /// `check --only` with a name that is no assignment.
    #[error("no assignment `{0}`")]
    UnknownOnly(String),
    /// Solution text outside the marked regions (how many lines, the first ones shown).
    #[error(
        "the copy would still contain solution text ({0} lines; move it into the marked \
         region or reword it):\n{1}"
    )]
    Leaks(usize, String),
    /// A path that cannot be resolved, created or written (the path, the cause).
    #[error("{0}: {1}")]
    Io(String, #[source] std::io::Error),
    /// The target directory builds another copy (the directory, its owner, this copy).
    #[error(
        "target directory {0} builds the copy {1}; give {2} its own (copies of the crate \
         share artifact names, so one could be graded with the other's build)"
    )]
    TargetOwned(String, String, String),
    /// `--build-dir` for a crate that is no copy `assignment make` wrote (the directory).
    #[error(
        "{0} is not a copy written by `pathspace assignment make` (its version has no \
         `+copy.` id), so it cannot share a build directory; leave out --build-dir"
    )]
    NotACopy(String),
    /// Two copies with one id in a build directory (the directory, the id, its owner, this
    /// copy).
    #[error(
        "build directory {0} builds the copy {2} with the id {1}; {3} has the same id (a copy \
         of a copy?): write it again with `pathspace assignment make`, or give it its own \
         --build-dir"
    )]
    IdTaken(String, String, String, String),
    /// cargo could not be started.
    #[error("cannot run cargo: {0}")]
    Cargo(#[source] std::io::Error),
    /// Some assignments did not pass (how many failed, of how many).
    #[error("{0} of {1} assignments failed")]
    Failed(usize, usize),
    /// An exercise cannot be graded.
    #[error(transparent)]
    Exercise(#[from] exercise::ExerciseError),
    /// Some claims of an exercise do not hold (how many, of how many).
    #[error("{0} of {1} claims of the exercise do not hold")]
    ClaimsFailed(usize, usize),
}

impl From<AssignmentError> for String {
    fn from(e: AssignmentError) -> Self {
        e.to_string()
    }
}

fn tests_of(a: &Assignment) -> String {
    a.tests
        .iter()
        .map(|t| t.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn list(tree: &Tree) -> Result<(), AssignmentError> {
    let registry = Registry::of_tree(tree)?;
    println!(
        "{:<26} {:<26} {:>5}  {:<36} graded tests",
        "assignment", "chapter", "hours", "prerequisites"
    );
    for a in &registry.assignments {
        println!(
            "{:<26} {:<26} {:>5}  {:<36} {}",
            a.name,
            a.chapter_file,
            a.hours,
            a.prerequisites.join(", "),
            tests_of(a)
        );
    }
    println!();
    println!(
        "{:<26} {:<26} {:>5}  question",
        "exercise", "chapter", "hours"
    );
    for e in &registry.exercises {
        println!(
            "{:<26} {:<26} {:>5}  {}",
            e.name, e.chapter_file, e.hours, e.question
        );
    }
    Ok(())
}

/// The file of a copy that names the assignments it was made with (what `check` grades).
pub const ASSIGNED_FILE: &str = "assigned.toml";

/// The assignments a copy was made with, from its [`ASSIGNED_FILE`].
pub fn assigned(dir: &Path) -> Option<Vec<String>> {
    #[derive(serde::Deserialize)]
    struct Assigned {
        assignments: Vec<String>,
    }
    let text = std::fs::read_to_string(dir.join(ASSIGNED_FILE)).ok()?;
    toml::from_str::<Assigned>(&text)
        .ok()
        .map(|a| a.assignments)
}

fn make(args: MakeArgs, tree: Tree) -> Result<(), AssignmentError> {
    course::check_copy_target(&args.out)?;
    let registry = Registry::of_tree(&tree)?;
    let chosen: Vec<&Assignment> = if args.all {
        registry.assignments.iter().collect()
    } else {
        if args.names.is_empty() {
            return Err(AssignmentError::NoName);
        }
        args.names
            .iter()
            .map(|n| {
                registry
                    .find(n)
                    .ok_or_else(|| AssignmentError::Unknown(n.clone()))
            })
            .collect::<Result<_, _>>()?
    };
    let mut copy = course::student_copy(&tree, &chosen)?;
    let names: Vec<String> = chosen.iter().map(|a| format!("{:?}", a.name)).collect();
    copy.tree.insert(
        ASSIGNED_FILE.to_string(),
        format!(
            "# The assignments this copy was made with: `pathspace assignment check` grades them.\n\
             assignments = [{}]\n",
            names.join(", ")
        )
        .into_bytes(),
    );
    let id = identity::fresh(&args.out);
    identity::stamp(&mut copy.tree, &id)?;
    let leaks = course::leaks(&copy);
    if !leaks.is_empty() {
        let shown: Vec<String> = leaks
            .iter()
            .take(MAX_LEAKS_SHOWN)
            .map(|(name, file, line, text)| format!("  {name}: {file}:{line}: `{text}`"))
            .collect();
        return Err(AssignmentError::Leaks(leaks.len(), shown.join("\n")));
    }
    course::write_copy(&copy, &args.out)?;
    for a in &chosen {
        eprintln!(
            "{}: blanked in {} (book/src/{}); graded by {}",
            a.name,
            a.files.join(", "),
            a.chapter_file,
            tests_of(a)
        );
    }
    println!(
        "wrote {} files to {} (copy {id}); grade with `pathspace assignment check {}`",
        copy.tree.len(),
        args.out.display(),
        args.out.display()
    );
    Ok(())
}

/// The outcome of one assignment's graded tests.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    Passed,
    /// The tests reached this assignment's `todo!()`.
    NotImplemented,
    /// A graded test failed: the test, the first lines of its failure.
    Failed(Option<(String, Vec<String>)>),
    BuildError,
}

impl Outcome {
    pub fn label(&self) -> &'static str {
        match self {
            Outcome::Passed => "passed",
            Outcome::NotImplemented => "failed (todo!)",
            Outcome::Failed(_) => "failed",
            Outcome::BuildError => "build error",
        }
    }
}

/// The name of the copy's root package (the crate its graded tests belong to).
fn package_name(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("Cargo.toml"))
        .ok()
        .and_then(|t| identity::package_name(&t))
        .unwrap_or_else(|| "pathspace".to_string())
}

fn cargo(dir: &Path, args: &CheckArgs) -> Command {
    let mut c = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    let package = package_name(dir);
    c.current_dir(dir);
    c.arg("test")
        .arg("--release")
        .arg("--package")
        .arg(&package);
    c.arg("--config").arg(format!(
        "profile.release.package.{package}.opt-level={}",
        args.opt_level
    ));
    // a student's edit recompiles only what it touched: without incremental compilation every
    // check of a one-line change rebuilds the whole crate (minutes on two busy cores)
    c.arg("--config").arg("profile.release.incremental=true");
    if let Some(t) = &args.target_dir {
        // cargo runs in the copy: a relative target directory means one from here
        let t = std::path::absolute(t).unwrap_or_else(|_| t.clone());
        c.arg("--target-dir").arg(t);
    }
    if let Some(b) = &args.build_dir {
        let b = std::path::absolute(b).unwrap_or_else(|_| b.clone());
        c.env("CARGO_BUILD_BUILD_DIR", b);
    }
    c
}

/// The build directory `check` gives Cargo: `--build-dir`, else the target directory of the
/// crate this binary was built from when it holds a release build, for a copy with an id
/// ([`identity`]); `None` leaves Cargo's default (the copy's target directory).
fn build_dir_for(args: &CheckArgs, built_from: &Path) -> Result<Option<PathBuf>, AssignmentError> {
    let toml = args.dir.join("Cargo.toml");
    let text = std::fs::read_to_string(&toml).map_err(io_at(&toml))?;
    let Some(id) = identity::of(&text) else {
        return match &args.build_dir {
            Some(_) => Err(AssignmentError::NotACopy(args.dir.display().to_string())),
            None => Ok(None),
        };
    };
    let built_from = built_from.join("target");
    let build = match &args.build_dir {
        Some(b) => b.clone(),
        None if built_from.join("release").is_dir() => built_from,
        None => return Ok(None),
    };
    claim_id(&build, &id, &args.dir)?;
    Ok(Some(build))
}

/// Records `dir` as the copy with id `id` in build directory `b`, or refuses when another
/// directory holds that id there.
fn claim_id(b: &Path, id: &str, dir: &Path) -> Result<(), AssignmentError> {
    let owners = b.join("pathspace-assignment-copies");
    let me = canonical(dir)?;
    let file = owners.join(format!("{id}.txt"));
    match std::fs::read_to_string(&file) {
        Ok(owner) if owner.trim() != me => Err(AssignmentError::IdTaken(
            b.display().to_string(),
            id.to_string(),
            owner.trim().to_string(),
            me,
        )),
        Ok(_) => Ok(()),
        Err(_) => {
            std::fs::create_dir_all(&owners).map_err(io_at(&owners))?;
            write_claim(&file, &me)
        }
    }
}

/// The error of an operation on `p`.
fn io_at(p: &Path) -> impl FnOnce(std::io::Error) -> AssignmentError {
    let p = p.display().to_string();
    move |e| AssignmentError::Io(p, e)
}

fn canonical(dir: &Path) -> Result<String, AssignmentError> {
    Ok(std::fs::canonicalize(dir)
        .map_err(io_at(dir))?
        .to_string_lossy()
        .to_string())
}

/// The file in a target directory that names the copy it builds.
const TARGET_OWNER_FILE: &str = "pathspace-assignment-copy.txt";

/// Records `dir` as the only copy built in target directory `t`, or refuses when another copy
/// owns it.
fn claim_target_dir(t: &Path, dir: &Path) -> Result<(), AssignmentError> {
    let me = canonical(dir)?;
    let owner_file = t.join(TARGET_OWNER_FILE);
    match std::fs::read_to_string(&owner_file) {
        Ok(owner) if owner.trim() != me => Err(AssignmentError::TargetOwned(
            t.display().to_string(),
            owner.trim().to_string(),
            me,
        )),
        Ok(_) => Ok(()),
        Err(_) => {
            std::fs::create_dir_all(t).map_err(io_at(t))?;
            write_claim(&owner_file, &me)
        }
    }
}

/// Writes the claim file `file` naming copy `me` through a temporary file: a full disk leaves no
/// empty claim that would later name no copy.
fn write_claim(file: &Path, me: &str) -> Result<(), AssignmentError> {
    Ok(crate::fsx::write_file_replacing(
        file,
        format!("{me}\n").as_bytes(),
    )?)
}

/// Number of tests a libtest summary reports as passed, summed over the output.
fn passed_count(out: &str) -> usize {
    out.lines()
        .filter_map(|l| l.strip_prefix("test result: "))
        .filter_map(|l| l.split(';').next())
        .filter_map(|l| l.split_whitespace().nth(1)?.parse::<usize>().ok())
        .sum()
}

fn check(mut args: CheckArgs, built_from: &Path) -> Result<(), AssignmentError> {
    if !args.dir.join("Cargo.toml").is_file() {
        return Err(CourseError::NoCargoToml(args.dir.display().to_string()).into());
    }
    let registry = Registry::read(&args.dir)?;
    let chosen: Vec<&Assignment> = match (&args.only, assigned(&args.dir)) {
        (Some(n), _) => {
            vec![registry
                .find(n)
                .ok_or_else(|| AssignmentError::UnknownOnly(n.clone()))?]
        }
        (None, Some(names)) if !args.all => names
            .iter()
            .map(|n| {
                registry
                    .find(n)
                    .ok_or_else(|| AssignmentError::UnknownOnly(n.clone()))
            })
            .collect::<Result<_, _>>()?,
        _ => registry.assignments.iter().collect(),
    };
    if let Some(t) = &args.target_dir {
        claim_target_dir(t, &args.dir)?;
    }
    args.build_dir = build_dir_for(&args, built_from)?;
    match &args.build_dir {
        Some(b) => eprintln!(
            "building in {} (dependencies shared with other copies and with the crate built there)",
            b.display()
        ),
        None => eprintln!("building in the copy's own target directory"),
    }
    let build_ok = build_graded(&args, &chosen)?;
    println!(
        "{:<26} {:<15} {:>8}  graded tests",
        "assignment", "result", "time"
    );
    let mut passed = 0;
    let mut failures = Vec::new();
    for (i, a) in chosen.iter().enumerate() {
        eprintln!("grading {} ({} of {})", a.name, i + 1, chosen.len());
        let start = Instant::now();
        let outcome = if build_ok {
            grade(&args, a)?
        } else {
            Outcome::BuildError
        };
        if outcome == Outcome::Passed {
            passed += 1;
        }
        println!(
            "{:<26} {:<15} {:>6.1} s  {}",
            a.name,
            outcome.label(),
            start.elapsed().as_secs_f64(),
            tests_of(a)
        );
        if let Outcome::Failed(Some(f)) = outcome {
            failures.push(f);
        }
    }
    println!("{passed} of {} assignments passed", chosen.len());
    for (test, lines) in &failures {
        println!();
        println!("{test} failed:");
        for l in lines {
            println!("    {l}");
        }
        println!("rerun it in {}: {}", args.dir.display(), rerun(test));
    }
    if passed == chosen.len() {
        Ok(())
    } else {
        Err(AssignmentError::Failed(chosen.len() - passed, chosen.len()))
    }
}

/// The command that reruns the graded test `t` (`TARGET::PATH`) in its copy.
fn rerun(t: &str) -> String {
    course::GradedTest::try_from(t.to_string()).map_or_else(|e| e, |g| g.command())
}

/// Builds the graded test binaries of `chosen` only, in one cargo call (in parallel, and once);
/// false when the copy does not compile.
fn build_graded(args: &CheckArgs, chosen: &[&Assignment]) -> Result<bool, AssignmentError> {
    let mut targets: Vec<&str> = chosen
        .iter()
        .flat_map(|a| a.tests.iter().map(|t| t.target.as_str()))
        .collect();
    targets.sort();
    targets.dedup();
    eprintln!("building the graded tests ({})", targets.join(", "));
    let mut build = cargo(&args.dir, args);
    build.arg("--no-run");
    for t in &targets {
        build.arg("--test").arg(t);
    }
    // Cargo's own progress (the crates it compiles, its bar on a terminal) and errors go
    // straight to the user: a cold build takes minutes
    let built = build
        .stdout(std::process::Stdio::null())
        .status()
        .map_err(AssignmentError::Cargo)?;
    Ok(built.success())
}

/// Runs an assignment's graded tests target by target, stopping at the first target that does
/// not pass.
fn grade(args: &CheckArgs, a: &Assignment) -> Result<Outcome, AssignmentError> {
    let mut outcome = Outcome::Passed;
    for target in a
        .tests
        .iter()
        .map(|t| t.target.as_str())
        .collect::<std::collections::BTreeSet<_>>()
    {
        if outcome != Outcome::Passed {
            break;
        }
        outcome = grade_target(args, a, target)?;
    }
    Ok(outcome)
}

/// Lines of a failure `check` prints under its table.
const FAILURE_LINES: usize = 8;

/// The first failing test of a libtest output and the first lines of its failure (the
/// `---- NAME stdout ----` section, the backtrace hint left out).
fn first_failure(target: &str, out: &str) -> Option<(String, Vec<String>)> {
    let mut lines = out.lines();
    let name = lines
        .by_ref()
        .find_map(|l| l.strip_prefix("---- ")?.strip_suffix(" stdout ----"))?
        .to_string();
    let body: Vec<String> = lines
        .take_while(|l| !l.starts_with("---- ") && !l.starts_with("failures:"))
        .filter(|l| !l.trim().is_empty() && !l.starts_with("note: run with `RUST_BACKTRACE"))
        .take(FAILURE_LINES)
        .map(str::to_string)
        .collect();
    Some((format!("{target}::{name}"), body))
}

/// The outcome of an assignment's graded tests in one test target.
fn grade_target(
    args: &CheckArgs,
    a: &Assignment,
    target: &str,
) -> Result<Outcome, AssignmentError> {
    let paths: Vec<&str> = a
        .tests
        .iter()
        .filter(|t| t.target == target)
        .map(|t| t.path.as_str())
        .collect();
    let mut c = cargo(&args.dir, args);
    c.env("RUST_BACKTRACE", "0");
    c.arg("--test").arg(target).arg("--").arg("--exact");
    c.args(&paths);
    let o = c.output().map_err(AssignmentError::Cargo)?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    Ok(
        if o.status.success() && passed_count(&text) == paths.len() {
            Outcome::Passed
        } else if text.contains(&format!("assignment {}:", a.name)) {
            Outcome::NotImplemented
        } else if o.status.success() {
            // a graded test that no longer exists must not count as passed
            Outcome::Failed(Some((
                format!("{target}::{}", paths.join(", ")),
                vec!["not every graded test ran: is one renamed or removed?".to_string()],
            )))
        } else if text.contains("could not compile") {
            Outcome::BuildError
        } else {
            Outcome::Failed(first_failure(target, &text))
        },
    )
}

/// `pathspace assignment exercise NAME [DIR...]`: judges the exercise's claims from the
/// studies and prints one line per claim.
fn grade_exercise(args: ExerciseArgs, tree: &Tree) -> Result<(), AssignmentError> {
    let registry = Registry::of_tree(tree)?;
    let e = registry
        .exercises
        .iter()
        .find(|e| e.name == args.name)
        .ok_or_else(|| exercise::ExerciseError::Unknown(args.name.clone()))?;
    let dirs: Vec<PathBuf> = if args.studies.is_empty() {
        e.studies
            .iter()
            .filter_map(|c| exercise::output_of(c).map(Path::to_path_buf))
            .collect()
    } else {
        args.studies.clone()
    };
    let verdicts = exercise::grade(e, &dirs)?;
    let failed = verdicts.iter().filter(|v| !v.passed).count();
    for v in &verdicts {
        println!(
            "{}: {}",
            if v.passed { "holds" } else { "not shown" },
            v.report
        );
    }
    if failed == 0 {
        println!("exercise {}: every claim holds", e.name);
        Ok(())
    } else {
        Err(AssignmentError::ClaimsFailed(failed, verdicts.len()))
    }
}
