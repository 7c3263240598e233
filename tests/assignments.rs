//! The book as a course (book: "Course use: assignments"): the `// ASSIGNMENT:` markers and the
//! registry `book/course.toml` agree, every graded test exists, every chapter names its
//! assignments, and a student copy with every assignment blanked
//!
//! - contains no line of any removed region, in any file (sources, tests, the book, examples);
//! - compiles;
//! - fails each graded test on that assignment's own `todo!()` (so each assignment's tests
//!   fail in a copy where it is blank, whatever the other blanks), while the same tests pass
//!   in the original (they are part of the normal suite; `assignment check` on the original
//!   is run here for one assignment to show the table's "passed" path).
//!
//! Cost: copies build in `target/assignments` (next to this build's `release`), whose `deps`
//! are hard links to the release build's (the same crates with the same profile, so Cargo
//! reuses them), and the copy's own crate is compiled at opt-level 0, which is what makes one
//! copy and eleven test binaries affordable (about 50 s from cold on two busy cores); in the blank copy every
//! graded test stops at its `todo!()` within milliseconds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use pathspace_course::{self as course, Assignment, Registry};

mod common;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The release profile's directory of this build (`.../target/release`, wherever
/// CARGO_TARGET_DIR puts it): this test runs from its `deps`.
fn release_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().and_then(Path::parent).unwrap().to_path_buf()
}

fn original() -> course::Tree {
    course::read_tree(&root()).unwrap()
}

fn registry() -> Registry {
    Registry::read(&root()).unwrap()
}

#[test]
fn every_marker_is_registered_and_every_assignment_is_marked() {
    course::check_registry(&original()).unwrap();
}

/// Every graded test's module path leads to a file that declares it as a test.
#[test]
fn every_graded_test_exists_at_its_module_path() {
    for a in &registry().assignments {
        for t in &a.tests {
            let decl = format!("#[test]\nfn {}()", t.function());
            let files = t.module_files();
            assert!(
                files.iter().any(|f| std::fs::read_to_string(root().join(f))
                    .is_ok_and(|text| text.contains(&decl))),
                "assignment {}: no #[test] fn {} in {}",
                a.name,
                t.function(),
                files.join(" or ")
            );
        }
    }
}

/// A graded test is addressed by a module path; anything else is refused when the registry is
/// read, and the address resolves to the module's files in both layouts.
#[test]
fn graded_tests_are_module_paths() {
    let t = course::GradedTest::try_from("spec::path::g::closed_forms".to_string()).unwrap();
    assert_eq!(
        (t.target.as_str(), t.path.as_str()),
        ("spec", "path::g::closed_forms")
    );
    assert_eq!(t.function(), "closed_forms");
    assert_eq!(
        t.command(),
        "cargo test --release --test spec -- --exact path::g::closed_forms"
    );
    assert_eq!(
        t.module_files(),
        ["tests/spec/path/g.rs", "tests/spec/path/g/mod.rs"]
    );
    for bad in ["closed_forms", "a::", "a b::c", "::c"] {
        assert!(
            course::GradedTest::try_from(bad.to_string()).is_err(),
            "{bad}"
        );
    }
}

#[test]
fn every_chapter_names_its_assignments_and_the_course_page_lists_all() {
    let course_page = std::fs::read_to_string(root().join("book/src/course.md")).unwrap();
    for a in &registry().assignments {
        let chapter = std::fs::read_to_string(root().join("book/src").join(&a.chapter_file))
            .unwrap_or_else(|e| panic!("{}: {e}", a.chapter_file));
        let check = chapter
            .split("## Check it yourself")
            .nth(1)
            .unwrap_or_else(|| panic!("{} has no 'Check it yourself' section", a.chapter_file));
        assert!(
            check.contains(&format!("`{}`", a.name)),
            "{}: 'Check it yourself' does not name assignment `{}`",
            a.chapter_file,
            a.name
        );
        assert!(
            course_page.contains(&format!("`{}`", a.name)),
            "course.md does not list assignment `{}`",
            a.name
        );
        let summary = std::fs::read_to_string(root().join("book/src/SUMMARY.md")).unwrap();
        assert!(summary.contains(&format!("({})", a.chapter_file)));
    }
}

/// The course page's syllabus is the registry's: its rows in the registry's order with the
/// same hours and prerequisites, and every exercise in its table; each exercise's studies are
/// commands the CLI parses, its chapter exists and names it.
#[test]
fn the_syllabus_and_the_exercises_on_the_course_page_are_the_registrys() {
    use clap::Parser;
    let registry = registry();
    let page = std::fs::read_to_string(root().join("book/src/course.md")).unwrap();
    let syllabus = page
        .split("## Syllabus")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("course.md has a Syllabus section");
    let rows: Vec<Vec<String>> = syllabus
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains("| `"))
        .map(|l| l.split('|').map(|c| c.trim().to_string()).collect())
        .collect();
    assert_eq!(
        rows.len(),
        registry.assignments.len(),
        "the syllabus has {} rows, the registry {} assignments",
        rows.len(),
        registry.assignments.len()
    );
    for (i, (row, a)) in rows.iter().zip(&registry.assignments).enumerate() {
        let prerequisites = if a.prerequisites.is_empty() {
            "—".to_string()
        } else {
            a.prerequisites
                .iter()
                .map(|p| format!("`{p}`"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let expected = [
            (i + 1).to_string(),
            format!("`{}`", a.name),
            a.hours.to_string(),
            prerequisites,
            format!("[picture]({})", a.picture),
        ];
        let got = [&row[1], &row[2], &row[4], &row[5], &row[6]];
        for (g, e) in got.iter().zip(&expected) {
            assert_eq!(*g, e, "syllabus row {}: got `{g}`, expected `{e}`", i + 1);
        }
    }
    assert!(
        registry.exercises.len() >= 4,
        "fewer than 4 measurement exercises"
    );
    for e in &registry.exercises {
        assert!(
            page.contains(&format!("| `{}` |", e.name)),
            "course.md does not list exercise `{}`",
            e.name
        );
        let chapter = std::fs::read_to_string(root().join("book/src").join(&e.chapter_file))
            .unwrap_or_else(|err| panic!("exercise {}: {}: {err}", e.name, e.chapter_file));
        assert!(
            chapter.contains(&format!("`{}`", e.name)),
            "{} does not name exercise `{}`",
            e.chapter_file,
            e.name
        );
        assert!(!e.claims.is_empty(), "exercise {} claims nothing", e.name);
        for c in &e.studies {
            let words = c.split_whitespace();
            if let Err(err) = pathspace::cli::Cli::try_parse_from(words) {
                panic!("exercise {}: `{c}` does not parse: {err}", e.name);
            }
            assert!(
                pathspace_course::exercise::output_of(c).is_some(),
                "exercise {}: `{c}` names no output (-o)",
                e.name
            );
        }
    }
}

/// The README and the course page state how many assignments there are; the registry decides.
#[test]
fn the_readme_and_the_course_page_count_the_assignments_right() {
    let n = registry().assignments.len();
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let course_page = std::fs::read_to_string(root().join("book/src/course.md")).unwrap();
    let said = format!("The book doubles as a course: {n} function bodies");
    assert!(readme.contains(&said), "README.md does not say `{said}`");
    let table = format!("`{n} of {n} assignments passed`");
    assert!(
        course_page.contains(&table),
        "course.md does not say {table}"
    );
}

#[test]
fn blanking_keeps_the_markers_and_replaces_the_body() {
    let registry = registry();
    let a = registry.find("characteristic").unwrap();
    let text = "fn f() -> u64 {\n    // ASSIGNMENT: characteristic\n    let x = 1;\n    x + 1\n    // END ASSIGNMENT\n}\n";
    let (out, removed) = course::blank(text, &[a]).unwrap();
    assert_eq!(removed, vec!["    let x = 1;", "    x + 1"]);
    assert_eq!(
        out,
        format!(
            "fn f() -> u64 {{\n    // ASSIGNMENT: characteristic\n    {}\n    // END ASSIGNMENT\n}}\n",
            course::todo_line(a)
        )
    );
    // other assignments' regions are left alone
    let b = registry.find("acceptance").unwrap();
    assert_eq!(course::blank(text, &[b]).unwrap().0, text);
    // malformed markers are errors
    assert!(course::regions("// ASSIGNMENT: a\n").is_err());
    assert!(course::regions("// END ASSIGNMENT\n").is_err());
    assert!(course::regions("// ASSIGNMENT: a\n// ASSIGNMENT: b\n").is_err());
}

#[test]
fn a_leaked_line_is_found_anywhere_in_the_copy() {
    let mut tree = original();
    let registry = registry();
    let a = registry.find("geometry_term").unwrap();
    let copy = course::student_copy(&tree, &[a]).unwrap();
    assert!(
        course::leaks(&copy).is_empty(),
        "{:?}",
        course::leaks(&copy)
    );
    // a chapter quoting the solution by hand (rather than by anchor) is caught
    let line = copy.removed[0]
        .1
        .iter()
        .find(|l| course::is_solution_text(l) && !copy.shared.contains(l.trim()))
        .expect("geometry_term removes a line of solution text")
        .clone();
    let page = tree.get_mut("book/src/path-space.md").unwrap();
    page.extend_from_slice(format!("\n```rust\n{line}\n```\n").as_bytes());
    let copy = course::student_copy(&tree, &[a]).unwrap();
    let leaks = course::leaks(&copy);
    assert!(
        leaks.iter().any(|l| l.1 == "book/src/path-space.md"),
        "{leaks:?}"
    );
}

/// Builds a copy's book into a fresh directory of its own under `target/assignments`; returns
/// (that directory, the directory of its HTML). The caller removes exactly the first.
fn build_book(copy: &Path, out: &Path) -> PathBuf {
    assert!(
        out.ends_with("book-html"),
        "refusing to build into {}",
        out.display()
    );
    let _ = std::fs::remove_dir_all(out);
    let mut book = mdbook_driver::MDBook::load(copy.join("book")).expect("the copy's book loads");
    book.config.build.build_dir = out.to_path_buf();
    book.build().expect("the copy's book builds");
    if out.join("html").is_dir() {
        out.join("html")
    } else {
        out.to_path_buf()
    }
}

/// Hard-links the release build's dependencies into `target/assignments/release`, so that
/// Cargo finds them fresh there (best effort: without it they are compiled once). The
/// directory is this test's own: the claims a copy of the whole target directory (another
/// checkout's, a CI cache) brought along are dropped, or `check` would refuse it as another
/// copy's.
fn seed_target_dir(target: &Path) {
    let _ = std::fs::remove_file(target.join("pathspace-assignment-copy.txt"));
    let _ = std::fs::remove_dir_all(target.join("pathspace-assignment-copies"));
    let release = release_dir();
    let dest = target.join("release");
    std::fs::create_dir_all(&dest).unwrap();
    for sub in ["deps", "build", ".fingerprint"] {
        if release.join(sub).is_dir() {
            let _ = Command::new("cp")
                .args(["-al", "-n"])
                .arg(release.join(sub))
                .arg(&dest)
                .status();
        }
    }
}

fn pathspace(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .args(args)
        .output()
        .unwrap()
}

/// Builds the copy's graded test binaries; returns test target name -> executable.
fn build_graded_tests(copy: &Path, target: &Path, files: &[&str]) -> BTreeMap<String, PathBuf> {
    let mut c = Command::new(env!("CARGO"));
    c.current_dir(copy)
        .args(["test", "--release", "--no-run", "--message-format=json"])
        .args(["--package", "pathspace"])
        .args(["--config", "profile.release.package.pathspace.opt-level=0"])
        // as `assignment check` builds, so that its check below reuses this build
        .args(["--config", "profile.release.incremental=true"])
        .arg("--target-dir")
        .arg(target);
    for f in files {
        c.arg("--test").arg(f);
    }
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "the student copy does not compile:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut exes = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Ok(v) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let kinds = &v["target"]["kind"];
        if let (Some(exe), true) = (
            v["executable"].as_str(),
            kinds
                .as_array()
                .is_some_and(|k| k.iter().any(|k| k == "test")),
        ) {
            let name = v["target"]["name"].as_str().unwrap().to_string();
            exes.insert(name, PathBuf::from(exe));
        }
    }
    exes
}

#[test]
fn a_copy_with_every_assignment_blank_compiles_and_fails_each_graded_test_on_its_own_todo() {
    let target = release_dir().parent().unwrap().join("assignments");
    let copy = target.join("all");
    let _ = std::fs::remove_dir_all(&copy);
    seed_target_dir(&target);

    // make: refuses to leave solution text anywhere (checked again in-process below)
    let out = pathspace(&[
        "assignment",
        "make",
        "--all",
        "--out",
        copy.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let toml = std::fs::read_to_string(copy.join("Cargo.toml")).unwrap();
    assert!(course::identity::of(&toml).is_some(), "the copy has no id");
    let registry = registry();
    let all: Vec<&Assignment> = registry.assignments.iter().collect();
    let in_memory = course::student_copy(&original(), &all).unwrap();
    assert!(course::leaks(&in_memory).is_empty());
    assert!(!copy.join("tests/assignments.rs").exists());
    for a in &registry.assignments {
        let removed = &in_memory.removed.iter().find(|r| r.0 == a.name).unwrap().1;
        assert!(
            removed.iter().any(|l| !l.trim().is_empty()),
            "{} removes nothing",
            a.name
        );
        for f in &a.files {
            let text = std::fs::read_to_string(copy.join(f)).unwrap();
            assert!(
                text.contains(&course::todo_line(a)),
                "{f}: no todo for {}",
                a.name
            );
        }
    }

    // the copy's book builds, and its listings show the todo!() instead of the solution
    let book_out = target.join("book-html");
    let html = build_book(&copy, &book_out);
    for (page, name) in [
        ("path-space.html", "geometry_term"),
        ("path-space.html", "characteristic"),
        ("phase-functions.html", "hg_eval"),
        ("phase-functions.html", "hg_sample"),
        ("table1-homogeneous.html", "free_flight"),
        ("mlt.html", "acceptance"),
        ("mlt.html", "propagation_perturbation"),
        ("smc-cache.html", "partial_sums"),
        ("smc-cache.html", "bspline_control_variate"),
    ] {
        let text = std::fs::read_to_string(html.join(page)).unwrap();
        assert!(
            text.contains(&format!("assignment {name}: see book chapter")),
            "{page} does not show the todo!() of {name}"
        );
    }
    let path_space = std::fs::read_to_string(html.join("path-space.html")).unwrap();
    assert!(!path_space.contains("cosine_factor(x, w) * cosine_factor(y, w) / d2"));
    let _ = std::fs::remove_dir_all(&book_out);

    // the copy compiles, and every graded test fails on its own assignment's todo!()
    let mut files: Vec<&str> = registry
        .assignments
        .iter()
        .flat_map(|a| a.tests.iter().map(|t| t.target.as_str()))
        .collect();
    files.sort();
    files.dedup();
    let exes = build_graded_tests(&copy, &target, &files);
    let mut problems = Vec::new();
    for a in &registry.assignments {
        for t in &a.tests {
            let exe = &exes[&t.target];
            let out = Command::new(exe)
                .current_dir(&copy)
                .args(["--exact", &t.path, "--test-threads", "1"])
                .env("RUST_BACKTRACE", "0")
                .output()
                .unwrap();
            let text = format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            if out.status.success() || !text.contains("1 failed") {
                problems.push(format!(
                    "assignment {}: {t} does not fail while blank",
                    a.name
                ));
            } else if !text.contains(&format!("assignment {}:", a.name)) {
                let why = text
                    .lines()
                    .find(|l| l.contains("panicked at"))
                    .map(|l| {
                        format!(
                            "{l} {}",
                            text.lines().skip_while(|x| *x != l).nth(1).unwrap_or("")
                        )
                    })
                    .unwrap_or_default();
                problems.push(format!(
                    "assignment {}: {t} fails, but not on its todo!(): {why}",
                    a.name
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));

    // the grading table: a blank assignment is "failed (todo!)", the original "passed"
    let target_s = target.to_str().unwrap();
    let out = pathspace(&[
        "assignment",
        "check",
        copy.to_str().unwrap(),
        "--only",
        "characteristic",
        "--target-dir",
        target_s,
        "--build-dir",
        target_s,
        "--opt-level",
        "0",
    ]);
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{table}");
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("characteristic") && l.contains("failed (todo!)")),
        "{table}"
    );
    // a wrong body fails with the test's own message and the command that reruns it
    let characteristic_rs = copy.join("src/path/characteristic.rs");
    let blank = std::fs::read_to_string(&characteristic_rs).unwrap();
    let todo = course::todo_line(registry.find("characteristic").unwrap());
    std::fs::write(
        &characteristic_rs,
        blank.replace(&todo, "{ let _ = vertices; 0b1101 }"),
    )
    .unwrap();
    let out = pathspace(&[
        "assignment",
        "check",
        copy.to_str().unwrap(),
        "--only",
        "characteristic",
        "--target-dir",
        target_s,
        "--build-dir",
        target_s,
        "--opt-level",
        "0",
    ]);
    std::fs::write(&characteristic_rs, blank).unwrap();
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{table}");
    for expected in [
        "characteristic             failed ",
        "spec::path::characteristic_of_figure_2_is_eleven failed:",
        "got 0b1101, expected 0b1011",
        "cargo test --release --test spec -- --exact path::characteristic_of_figure_2_is_eleven",
    ] {
        assert!(table.contains(expected), "no `{expected}` in:\n{table}");
    }
    // another copy (here the original) needs its own target directory: the two crates' artifacts
    // have the same names, and Cargo judges freshness by modification times
    let out = pathspace(&[
        "assignment",
        "check",
        root().to_str().unwrap(),
        "--target-dir",
        target_s,
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("give"),
        "a shared target directory is refused"
    );
    let target_original = release_dir().parent().unwrap().join("assignments-original");
    seed_target_dir(&target_original);
    let out = pathspace(&[
        "assignment",
        "check",
        root().to_str().unwrap(),
        "--only",
        "characteristic",
        "--target-dir",
        target_original.to_str().unwrap(),
        "--opt-level",
        "0",
    ]);
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{table}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("characteristic") && l.contains("passed")),
        "{table}"
    );
}

/// Copies share a build directory by their ids; the two ways that sharing could grade one
/// build for another are refused before anything is built: a copy of a copy (one id in two
/// directories), and a crate with no id at all (the original, or a copy from before ids).
#[test]
fn a_shared_build_directory_takes_only_copies_with_their_own_id() {
    let dir = common::cli::scratch("assignments", "ids");
    let (a, b, build) = (dir.join("a"), dir.join("b"), dir.join("build"));
    for d in [&a, &b] {
        let out = common::cli::pathspace(&[
            "assignment",
            "make",
            "characteristic",
            "--out",
            d.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", common::cli::stderr(&out));
    }
    let id = |d: &Path| {
        course::identity::of(&std::fs::read_to_string(d.join("Cargo.toml")).unwrap()).unwrap()
    };
    // the copy names what it was made with: `check` grades that, not the whole registry
    assert_eq!(
        course::assignment::assigned(&a),
        Some(vec!["characteristic".to_string()])
    );
    assert_ne!(id(&a), id(&b), "two copies got one id");
    // b becomes a copy of a, after a claimed its id in the build directory
    std::fs::copy(a.join("Cargo.toml"), b.join("Cargo.toml")).unwrap();
    let owners = build.join("pathspace-assignment-copies");
    std::fs::create_dir_all(&owners).unwrap();
    let a_path = std::fs::canonicalize(&a).unwrap();
    std::fs::write(
        owners.join(format!("{}.txt", id(&a))),
        format!("{}\n", a_path.display()),
    )
    .unwrap();
    let check = |d: &Path| {
        common::cli::pathspace(&[
            "assignment",
            "check",
            d.to_str().unwrap(),
            "--build-dir",
            build.to_str().unwrap(),
        ])
    };
    let err = common::cli::stderr(&check(&b));
    assert!(
        err.contains(&format!("the id {}", id(&a))) && err.contains("has the same id"),
        "{err}"
    );
    let err = common::cli::stderr(&check(&root()));
    assert!(err.contains("is not a copy written by"), "{err}");
}
