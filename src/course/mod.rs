//! The book as a course: the registry of assignments and the student copy of the crate
//! (book: "Course use: assignments").
//!
//! An assignment is a region of a function body marked in the source by a line
//! `// ASSIGNMENT: name` and a line `// END ASSIGNMENT`; the signature and the doc comment stay,
//! the body is what the student writes. One assignment may mark several bodies (a sampler and
//! its pdf). [`ASSIGNMENTS`] names, for each, the chapter that derives it, the files that hold
//! its regions and the tests that grade it; `tests/assignments.rs` checks that the markers and
//! the registry agree, that a copy with every region blanked compiles, that each assignment's
//! graded tests fail there on its own `todo!()`, and that no line of a removed region survives
//! anywhere in the copy (the book includes code by anchor, so it shows the `todo!()` too).

pub mod assignment;
pub mod identity;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One graded test: `cargo test --release --test FILE -- --exact NAME`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GradedTest {
    /// The test file under `tests/`, without `.rs`.
    pub file: &'static str,
    /// The test function.
    pub name: &'static str,
}

/// An assignment: a marked region (or several) that a student copy replaces by `todo!()`.
#[derive(Clone, Copy, Debug)]
pub struct Assignment {
    /// The name after `// ASSIGNMENT:`.
    pub name: &'static str,
    /// The chapter's title, as in `book/src/SUMMARY.md`.
    pub chapter: &'static str,
    /// The chapter's file under `book/src/`.
    pub chapter_file: &'static str,
    /// The source files holding the marked regions.
    pub files: &'static [&'static str],
    /// What the student writes, in one line.
    pub task: &'static str,
    /// The tests that grade it: they pass on the original and fail while the region is blank.
    pub tests: &'static [GradedTest],
}

const fn t(file: &'static str, name: &'static str) -> GradedTest {
    GradedTest { file, name }
}

/// Every assignment, in the order of the book.
pub const ASSIGNMENTS: &[Assignment] = &[
    Assignment {
        name: "deflection_cosine",
        chapter: "Notation and conventions",
        chapter_file: "conventions.md",
        files: &["src/conventions.rs"],
        task: "the deflection cosine of a phase function when wo and wi both point away from the vertex",
        tests: &[t("phase", "the_deflection_cosine_follows_the_convention")],
    },
    Assignment {
        name: "uniform_triangle",
        chapter: "Scenes and geometry",
        chapter_file: "scenes.md",
        files: &["src/math/warp.rs"],
        task: "a uniform point on a triangle from two uniform numbers (Heitz 2019), density 2",
        tests: &[t("warp", "uniform_triangle_is_uniform_on_the_triangle")],
    },
    Assignment {
        name: "transmittance",
        chapter: "The transport equations (eqs. 1–3)",
        chapter_file: "transport-equations.md",
        files: &["src/medium/homogeneous.rs"],
        task: "tau = exp(-sigma_t d) of eq. (3) in a homogeneous medium, infinite d included",
        tests: &[t("free_flight", "transmittance_is_exp_minus_sigma_t_d")],
    },
    Assignment {
        name: "hg_eval",
        chapter: "Phase functions",
        chapter_file: "phase-functions.md",
        files: &["src/medium/phase.rs"],
        task: "the Henyey-Greenstein phase function of the deflection cosine, without cancellation",
        tests: &[
            t("phase", "hg_matches_its_closed_form"),
            t(
                "phase",
                "every_phase_function_integrates_to_one_over_the_deflection_cosine",
            ),
        ],
    },
    Assignment {
        name: "hg_sample",
        chapter: "Phase functions",
        chapter_file: "phase-functions.md",
        files: &["src/medium/phase.rs"],
        task: "sample the Henyey-Greenstein deflection cosine by inverting its CDF",
        tests: &[
            t("phase", "hg_mean_deflection_cosine_is_g"),
            t("phase", "sampling_agrees_with_pdf_by_chi_square"),
        ],
    },
    Assignment {
        name: "fresnel",
        chapter: "Surface scattering (eq. 2)",
        chapter_file: "bsdf.md",
        files: &["src/bsdf/mod.rs"],
        task: "the Fresnel reflectance of a dielectric interface, total internal reflection included",
        tests: &[
            t("bsdf", "fresnel_at_normal_incidence_is_the_squared_index_ratio"),
            t("bsdf", "dielectric_reflects_totally_beyond_the_critical_angle"),
        ],
    },
    Assignment {
        name: "ggx_visible_normals",
        chapter: "Surface scattering (eq. 2)",
        chapter_file: "bsdf.md",
        files: &["src/bsdf/microfacet.rs"],
        task: "sample GGX's visible normals (Heitz 2018): stretch, squeeze the disk, lift, unstretch",
        tests: &[t("microfacet", "rough_conductor_samples_its_density")],
    },
    Assignment {
        name: "free_flight",
        chapter: "Table 1: homogeneous media",
        chapter_file: "table1-homogeneous.md",
        files: &["src/medium/homogeneous.rs"],
        task: "Table 1: sample a free-flight distance (one-sample MIS over channels) and its pdf",
        tests: &[
            t("free_flight", "gray_collision_distances_follow_the_exponential_cdf"),
            t("free_flight", "free_flight_pdf_matches_the_sampled_pdf"),
            t(
                "free_flight",
                "collision_density_and_passing_probability_sum_to_one",
            ),
        ],
    },
    Assignment {
        name: "ratio_tracking",
        chapter: "Table 1: inhomogeneous media",
        chapter_file: "table1-inhomogeneous.md",
        files: &["src/medium/heterogeneous.rs"],
        task: "ratio tracking: an unbiased transmittance estimate against a majorant grid",
        tests: &[t(
            "media_inhomogeneous",
            "ratio_and_delta_tracking_transmittance_are_unbiased",
        )],
    },
    Assignment {
        name: "next_event",
        chapter: "The Neumann series and the path tracer (eq. 4)",
        chapter_file: "neumann-series.md",
        files: &["src/integrator/path.rs"],
        task: "next-event estimation: sample a light, test visibility and transmittance, weight by MIS",
        tests: &[
            t("transport", "meter_under_point_light_follows_inverse_square"),
            t("transport", "meter_measures_cosine_law"),
        ],
    },
    Assignment {
        name: "geometry_term",
        chapter: "Path space with media (eqs. 5–7)",
        chapter_file: "path-space.md",
        files: &["src/path/geometry_term.rs"],
        task: "the generalized geometry term G of sec. 3.2, surface and medium vertices alike",
        tests: &[t("path_space", "geometry_term_closed_forms")],
    },
    Assignment {
        name: "characteristic",
        chapter: "Path space with media (eqs. 5–7)",
        chapter_file: "path-space.md",
        files: &["src/path/characteristic.rs"],
        task: "the characteristic l of a path (sec. 3.1): one bit per vertex, 1 on surfaces",
        tests: &[t("path_space", "characteristic_of_figure_2_is_eleven")],
    },
    Assignment {
        name: "power_heuristic",
        chapter: "Bidirectional path tracing",
        chapter_file: "bdpt.md",
        files: &["src/integrator/path.rs"],
        task: "Veach's power heuristic (beta = 2) for two strategies, infinite densities included",
        tests: &[t("path_space", "power_heuristic_by_hand")],
    },
    Assignment {
        name: "acceptance",
        chapter: "Metropolis light transport (eq. 8)",
        chapter_file: "mlt.md",
        files: &["src/integrator/mlt/acceptance.rs"],
        task: "the Metropolis-Hastings acceptance probability of eq. (8)",
        tests: &[t("mlt", "acceptance_is_eq_8")],
    },
    Assignment {
        name: "propagation_perturbation",
        chapter: "Metropolis light transport (eq. 8)",
        chapter_file: "mlt.md",
        files: &["src/integrator/mlt/mutation/propagation.rs"],
        task: "the propagation perturbation of sec. 5.2.2 and its transition density T(x -> y)",
        tests: &[
            t(
                "mlt_mutations",
                "propagation_perturbation_proposals_follow_t_along_the_line_and_out_of_the_medium",
            ),
        ],
    },
    Assignment {
        name: "inverse_distance",
        chapter: "MLT experiments",
        chapter_file: "mlt-experiments.md",
        files: &["src/integrator/mlt/mutation/mod.rs"],
        task: "perturbation sizes with p(D) ~ 1/D: Veach's eq. (11.11) and its pdf",
        tests: &[t("mlt", "inverse_distance_follows_one_over_d")],
    },
    Assignment {
        name: "light_map_inverse",
        chapter: "Enlightened local path sampling: the adjoint image and particles",
        chapter_file: "enlightened-adjoint.md",
        files: &["src/enlightened/adjoint.rs"],
        task: "F^-1: the point of the unit square that the light-sampling map F sends to a light point",
        tests: &[t("enlightened", "light_map_round_trips")],
    },
    Assignment {
        name: "small_step",
        chapter: "Enlightened local path sampling: the adjoint image and particles",
        chapter_file: "enlightened-adjoint.md",
        files: &["src/math/primary_sample.rs"],
        task: "the small step of primary sample space: a wrapped normal offset, symmetric, n steps at once",
        tests: &[
            t("primary_sample", "small_steps_keep_the_target_invariant"),
            t("primary_sample", "mixed_steps_keep_the_target_invariant"),
        ],
    },
    Assignment {
        name: "equal_area_texel",
        chapter: "Enlightened local path sampling: guiding",
        chapter_file: "enlightened-guiding.md",
        files: &["src/enlightened/direction_map.rs"],
        task: "the texel of a direction in the equal-solid-angle map (rows uniform in cos theta)",
        tests: &[t("guiding", "direction_map_texels_round_trip")],
    },
    Assignment {
        name: "combined_estimator",
        chapter: "Sequential Monte Carlo adaptation (Pegoraro et al. 2008)",
        chapter_file: "smc.md",
        files: &["src/integrator/smc/estimator.rs"],
        task: "one sample of the combined estimator of eq. (1): control variate and importance sampling",
        tests: &[t("smc_unbiased", "combined_estimator_is_eq_1")],
    },
    Assignment {
        name: "partial_sums",
        chapter: "SMC: the radiance cache",
        chapter_file: "smc-cache.md",
        files: &["src/integrator/smc/partial_sums.rs"],
        task: "the tree of partial sums: O(log N) update of a cell and O(log N) sampling",
        tests: &[t(
            "smc_cache",
            "partial_sums_sample_cells_in_proportion_and_keep_the_root_equal_to_the_sum",
        )],
    },
    Assignment {
        name: "bspline_control_variate",
        chapter: "SMC: the radiance cache",
        chapter_file: "smc-cache.md",
        files: &["src/integrator/smc/bspline.rs"],
        task: "the order-1 B-spline reconstruction with polar values (the control variate g of cv2)",
        tests: &[
            t(
                "smc_cache",
                "order1_reconstruction_interpolates_the_coefficients_at_cell_centres",
            ),
            t("smc_cache", "polar_values_remove_the_pole_discontinuity"),
        ],
    },
    Assignment {
        name: "cv_roulette",
        chapter: "SMC: the estimators",
        chapter_file: "smc-estimators.md",
        files: &["src/integrator/smc/walk.rs"],
        task: "Russian roulette that ends a path at the cache's value c instead of at zero",
        tests: &[t("smc_unbiased", "roulette_is_unbiased_for_any_c")],
    },
    Assignment {
        name: "fit_power_law",
        chapter: "Measuring a renderer",
        chapter_file: "measuring.md",
        files: &["src/measure/stats.rs"],
        task: "least squares in log-log space: the order of convergence and its standard error",
        tests: &[t("measure", "power_law_fit_recovers_exact_power_laws")],
    },
];

/// The marker that opens a region.
pub const BEGIN: &str = "// ASSIGNMENT:";
/// The marker that closes a region.
pub const END: &str = "// END ASSIGNMENT";

/// The assignment called `name`.
pub fn find(name: &str) -> Option<&'static Assignment> {
    ASSIGNMENTS.iter().find(|a| a.name == name)
}

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
    #[error(transparent)]
    Output(#[from] crate::image_io::ImageError),
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
    for d in DIRS {
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

/// Checks that the markers of `tree` and [`ASSIGNMENTS`] agree: every marker is registered
/// (with its file), every assignment has at least one region, and only in its listed files.
pub fn check_registry(tree: &Tree) -> Result<(), CourseError> {
    let marks = markers(tree)?;
    let mut problems = Vec::new();
    for (file, r) in &marks {
        match find(&r.name) {
            None => problems.push(format!(
                "{file}:{}: assignment `{}` is not in the registry (src/course/mod.rs)",
                r.begin, r.name
            )),
            Some(a) if !a.files.contains(&file.as_str()) => problems.push(format!(
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
    for a in ASSIGNMENTS {
        for f in a.files {
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
    let mut names: Vec<&str> = ASSIGNMENTS.iter().map(|a| a.name).collect();
    names.sort();
    names.dedup();
    if names.len() != ASSIGNMENTS.len() {
        problems.push("two assignments share a name".to_string());
    }
    if problems.is_empty() {
        Ok(())
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
            .filter(|a| a.files.contains(&path.as_str()))
            .collect();
        if touched.is_empty() {
            out.insert(path.clone(), bytes.clone());
            continue;
        }
        let text = std::str::from_utf8(bytes).map_err(|_| CourseError::NotUtf8(path.clone()))?;
        for a in &touched {
            let (_, lines) = blank(text, &[a]).map_err(|e| CourseError::Marker(path.clone(), e))?;
            let slot = removed.iter_mut().find(|(n, _)| n == a.name).unwrap();
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
    Ok(crate::image_io::check_output_dir(out)?)
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
