//! The index of the test tree. The tests are laid out like the code: the module `a::b` of the
//! crate `tests/spec/` specifies `src/a/b.rs` (or `src/a/b/mod.rs`), and the sibling crates
//! `tests/oracles/`, `tests/invariants/`, `tests/inputs/` and `tests/repository/` hold what
//! judges the renderer as a whole. Here:
//!
//! - every module of `src/` has its spec module at the mirrored path, or is named in
//!   [`COVERED`] with the test module that covers it and why, so a new module cannot arrive
//!   without a place in the specification;
//! - every entry of [`COVERED`] is true: its module exists, has no spec module (else the entry
//!   is stale) and its covering test module exists;
//! - every file of a test crate is declared by a `mod` (an undeclared file is silently not
//!   compiled, so its tests would never run).

use std::path::{Path, PathBuf};

/// The modules of `src/` without a spec module of their own: (module, the test module that
/// covers it, why).
const COVERED: &[(&str, &str, &str)] = &[
    (
        "bidir",
        "spec::path",
        "the bidirectional engine's strategies against path space's densities and MIS weights",
    ),
    (
        "bidir::connect",
        "invariants::bdpt_weights",
        "a connection's MIS weight from shared values equals its recomputation",
    ),
    (
        "bidir::mis",
        "invariants::bdpt_weights",
        "the changed densities of each connection's weight",
    ),
    (
        "bidir::next_event",
        "spec::path",
        "next-event strategies are among those whose weights sum to one",
    ),
    (
        "bidir::sensor",
        "spec::integrator::reach",
        "the sensor connections of the light tracer and BDPT",
    ),
    (
        "bidir::walk",
        "invariants::path_verify",
        "every density a walk caches equals its recomputation",
    ),
    (
        "bsdf::dielectric",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "bsdf::lambert",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "bsdf::mirror",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "bsdf::named_conductor",
        "spec::bsdf::conductor",
        "the named table against Mitsuba's values, with the conductor it feeds",
    ),
    (
        "bsdf::null",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "bsdf::plastic",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "bsdf::rough_dielectric",
        "spec::bsdf::microfacet",
        "the rough dielectric with the other microfacet models",
    ),
    (
        "bsdf::thin_dielectric",
        "spec::bsdf::contract",
        "the contract run over every model",
    ),
    (
        "cli::converge",
        "spec::measure",
        "`pathspace converge` run by the binary",
    ),
    (
        "cli::diff",
        "spec::measure",
        "`pathspace diff` run by the binary against hand-computed metrics",
    ),
    (
        "cli::info",
        "inputs::error_contract",
        "every enumerated value checked by `info` as well as `render`",
    ),
    (
        "cli::interrupt",
        "spec::render::checkpoint",
        "SIGINT and SIGTERM stop a render that resumes bit for bit",
    ),
    (
        "cli::merge",
        "spec::render::provenance",
        "`merge` refuses inputs that are not independent renders",
    ),
    (
        "cli::render",
        "spec::cli",
        "what a newcomer meets around a render",
    ),
    (
        "cli::render_args",
        "spec::integrator::settings",
        "the flags parse into the schema's options, and a flag an integrator does not take is refused",
    ),
    (
        "cli::resume",
        "spec::render::checkpoint",
        "`resume` continues an interrupted render bit for bit",
    ),
    (
        "cli::rooms",
        "spec::scene::light_tree",
        "the rooms scene is the light tree's test bed",
    ),
    (
        "conventions",
        "spec::medium::phase",
        "the deflection cosine's convention and its phase functions",
    ),
    (
        "enlightened::adjoint",
        "spec::enlightened",
        "the adjoint image of Kristensen 2010, ch. 5",
    ),
    (
        "enlightened::direction_map",
        "spec::enlightened::guide",
        "equal-area maps: density integrates to one, sampler against density",
    ),
    (
        "enlightened::metropolis",
        "spec::enlightened",
        "the Metropolis particle sampler",
    ),
    (
        "enlightened::particles",
        "spec::enlightened",
        "the particles and their weights",
    ),
    (
        "enlightened::regions",
        "spec::enlightened::guide",
        "the guide's regions",
    ),
    (
        "enlightened::technique",
        "spec::enlightened::guide",
        "the guided technique's density",
    ),
    (
        "figures",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::chain",
        "spec::path",
        "its chain's weights are checked against the power heuristic of its end densities",
    ),
    (
        "figures::film_points",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::free_flight",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::halo",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::light_point",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::mutations",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::particles",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::path",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::side",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::smc",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "figures::walks",
        "repository::figures",
        "the committed diagrams are what the code draws",
    ),
    (
        "film",
        "oracles::transport",
        "every estimate of the oracles is read from a film",
    ),
    (
        "geometry::aabb",
        "spec::geometry",
        "the BVH against brute force",
    ),
    (
        "geometry::bvh",
        "spec::geometry",
        "the BVH against brute force, either insertion order",
    ),
    (
        "geometry::wide",
        "spec::geometry",
        "the wide BVH's hits equal the brute-force ones",
    ),
    (
        "geometry::leaf",
        "spec::geometry",
        "the hits of the leaves' triangle lanes are the primitives' own bit for bit",
    ),
    (
        "geometry::pages",
        "spec::geometry",
        "the eight-wide hits bit for bit on an 80,000-triangle sphere, whose blocks (over 2 MiB) \
         take the huge-page allocation; its unit test reads back arrays on both sides of 2 MiB",
    ),
    (
        "image_io",
        "inputs::writes",
        "atomic writes, and every EXR read back",
    ),
    (
        "image_io::png_input",
        "spec::texture",
        "the PNG fixture read through a bitmap texture, raw and sRGB-decoded, against Mitsuba 3's lookups",
    ),
    (
        "scene::build::textures",
        "spec::texture",
        "textures built from TOML keys (every filter, wrap mode, raw, to_uv) and looked up against Mitsuba 3",
    ),
    (
        "texture::bitmap",
        "spec::texture",
        "bilinear and nearest lookups, wrap modes and sRGB against Mitsuba 3's values and identities",
    ),
    (
        "texture::checkerboard",
        "spec::texture",
        "the pattern and to_uv against Mitsuba 3's values",
    ),
    (
        "image_io::rgbe",
        "spec::scene::envmap",
        "Radiance files written by the test, run-length encoded and flat, and their defects",
    ),
    (
        "integrator",
        "oracles::agreement",
        "every integrator through the one interface, against the reference",
    ),
    (
        "integrator::bdpt",
        "spec::integrator::reach",
        "BDPT's strategies and what they reach",
    ),
    (
        "integrator::bdpt::combine",
        "oracles::agreement",
        "BDPT's combined image against the reference",
    ),
    (
        "integrator::bdpt::strategy_images",
        "inputs::writes",
        "the strategy images are written like every output",
    ),
    (
        "integrator::mlt::acceptance",
        "spec::integrator::mlt",
        "acceptance against the densities both ways, eq. (8)",
    ),
    (
        "integrator::mlt::contribution",
        "spec::integrator::mlt",
        "the contribution and reuse of edge factors",
    ),
    (
        "integrator::mlt::init",
        "spec::integrator::mlt",
        "the chains' start and the normalization",
    ),
    (
        "integrator::mlt::mutation::bidirectional",
        "spec::integrator::mlt::mutation",
        "each mutation against its transition density",
    ),
    (
        "integrator::mlt::mutation::light",
        "spec::integrator::mlt::mutation",
        "each mutation against its transition density",
    ),
    (
        "integrator::mlt::mutation::multichain",
        "spec::integrator::mlt::mutation",
        "each mutation against its transition density",
    ),
    (
        "integrator::mlt::mutation::propagation",
        "spec::integrator::mlt::mutation",
        "each mutation against its transition density",
    ),
    (
        "integrator::mlt::mutation::sensor",
        "spec::integrator::mlt::mutation",
        "each mutation against its transition density",
    ),
    (
        "integrator::mlt::trace",
        "spec::integrator::mlt::mutation",
        "the traced paths the mutations start from",
    ),
    (
        "integrator::smc",
        "spec::integrator::smc::march",
        "SMC's estimators in media, with the cache's tests beside",
    ),
    (
        "integrator::smc::bspline",
        "spec::integrator::smc::cache",
        "the B-spline control variate",
    ),
    (
        "integrator::smc::distance",
        "invariants::smc_unbiased",
        "the adaptive distance densities stay unbiased",
    ),
    (
        "integrator::smc::estimator",
        "invariants::smc_unbiased",
        "both estimator forms stay unbiased",
    ),
    (
        "integrator::smc::grid",
        "spec::integrator::smc::cache",
        "the (s, t) grid",
    ),
    (
        "integrator::smc::octree",
        "spec::integrator::smc::cache",
        "the cache's tree of cells",
    ),
    (
        "integrator::smc::partial_sums",
        "spec::integrator::smc::cache",
        "the tree of partial sums",
    ),
    (
        "integrator::smc::walk",
        "invariants::smc_unbiased",
        "the SMC walk stays unbiased while its predicates adapt",
    ),
    ("math", "spec::math::warp", "the math layer's samplers"),
    (
        "math::distribution",
        "spec::math::warp",
        "the discrete and piecewise distributions beside the warps",
    ),
    (
        "math::frame",
        "spec::math::warp",
        "frames carry every warped direction",
    ),
    (
        "math::spherical",
        "oracles::slab",
        "the spherical helpers of the slab oracle's angles",
    ),
    (
        "measure::chart",
        "spec::measure",
        "the measuring chapter's charts",
    ),
    (
        "measure::convergence",
        "spec::measure",
        "the convergence fit on exact power laws",
    ),
    ("measure::heatmap", "spec::measure", "the error heat map"),
    (
        "measure::metrics",
        "spec::measure",
        "error metrics against hand-computed values",
    ),
    (
        "measure::stats",
        "spec::measure",
        "the measurements' statistics",
    ),
    ("measure::study", "spec::measure", "the convergence study"),
    (
        "medium",
        "spec::medium::homogeneous",
        "the medium interface: free flight and transmittance",
    ),
    (
        "medium::grid",
        "spec::medium::heterogeneous",
        "grid media, in the inhomogeneous media's spec",
    ),
    (
        "medium::procedural",
        "spec::medium::heterogeneous",
        "procedural media, in the inhomogeneous media's spec",
    ),
    (
        "path::characteristic",
        "spec::path",
        "the characteristic of figure 2",
    ),
    (
        "path::contribution",
        "spec::path",
        "f_j / p against the sampler's own density",
    ),
    (
        "path::distance",
        "spec::medium::equiangular",
        "the distance samplers, equiangular among them",
    ),
    (
        "path::geometry_term",
        "spec::path",
        "the generalized G term's closed forms",
    ),
    (
        "path::pdf",
        "spec::path",
        "the path densities of each technique",
    ),
    (
        "path::subpath",
        "invariants::path_verify",
        "subpaths' cached values equal their recomputation",
    ),
    (
        "path::technique",
        "spec::path",
        "the techniques and their weights",
    ),
    (
        "path::verify",
        "invariants::path_verify",
        "Path::verify as an invariant of every sampler",
    ),
    (
        "path::vertex",
        "spec::path",
        "vertices of surfaces and media in path space",
    ),
    ("render", "spec::render::run", "the render as one call"),
    (
        "render::memory",
        "spec::cli::reference",
        "a render above --max-memory is refused before any work",
    ),
    (
        "render::plan",
        "spec::render::shard",
        "the pass plan: shards hold the single run's passes",
    ),
    (
        "render::session",
        "spec::render::run",
        "the session's image bit for bit through the API",
    ),
    (
        "scene::build",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::hidden",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::lights",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::materials",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::media",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::normals",
        "spec::scene::normals",
        "smooth meshes' normals, built and rendered",
    ),
    (
        "scene::build::ply",
        "inputs::mitsuba_import",
        "PLY meshes read for imported scenes",
    ),
    (
        "scene::build::serialized",
        "inputs::serialized",
        "Mitsuba's serialized meshes against what Mitsuba 3 loads",
    ),
    (
        "scene::build::sensors",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::shapes",
        "inputs::scene_errors",
        "every key of the scene file, built or refused",
    ),
    (
        "scene::build::values",
        "inputs::error_contract",
        "every value checked at its key",
    ),
    (
        "scene::camera",
        "oracles::transport",
        "the sensor's measurements of analytic scenes",
    ),
    (
        "scene::emitters",
        "oracles::emission",
        "emitters and emitting media against closed forms",
    ),
    (
        "scene::file",
        "inputs::scene_errors",
        "the scene file's error contract",
    ),
    (
        "scene::file::diagnostics",
        "inputs::scene_errors",
        "every error names the file, the line and the key",
    ),
    (
        "scene::file::fixed",
        "inputs::error_contract",
        "fixed-length arrays checked at their key",
    ),
    (
        "scene::file::limits",
        "inputs::bounds",
        "bounded cost for every accepted input",
    ),
    (
        "scene::mitsuba",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::include",
        "inputs::mitsuba_import",
        "included scenes against a hand-written twin, and errors at the included file's lines",
    ),
    (
        "scene::mitsuba::plugins",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::plugins::bsdfs",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::plugins::emitters",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::plugins::media",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::plugins::sensor",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::plugins::shapes",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::mitsuba::spectrum",
        "spec::spectrum::cie",
        "lists and `.spd` files against the colours Mitsuba 3 gives them",
    ),
    (
        "scene::mitsuba::props",
        "inputs::mitsuba_import",
        "each Mitsuba convention against a hand-written twin",
    ),
    (
        "scene::segments",
        "spec::scene",
        "edges by any-hit query give the plain segment walk's bits",
    ),
    (
        "scene::sensor",
        "oracles::transport",
        "the sensor's measurements of analytic scenes",
    ),
    (
        "scene::source",
        "inputs::mitsuba_import",
        "files read and dispatched by format, XML among them",
    ),
    (
        "spectrum",
        "oracles::transport",
        "RGB radiance of every oracle",
    ),
    (
        "integrator::pssmlt::kernel",
        "spec::integrator::pssmlt",
        "the chain's kernel: exact balance on an enumerable target",
    ),
    (
        "integrator::pssmlt::sample",
        "spec::integrator::pssmlt",
        "the primary sample vector the chain perturbs",
    ),
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every module under `dir` by path (`a::b` for `a/b.rs` and for `a/b/mod.rs`); the crate
/// roots `lib.rs` and `main.rs` are not modules.
fn modules(dir: &Path, prefix: &str, out: &mut Vec<String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let full = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}::{name}")
        };
        if path.is_dir() {
            modules(&path, &full, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            match name.as_str() {
                "mod" if !prefix.is_empty() => out.push(prefix.to_string()),
                "lib" | "main" | "mod" if prefix.is_empty() => {}
                _ => out.push(full),
            }
        }
    }
}

fn src_modules(src: &Path) -> Vec<String> {
    let mut out = Vec::new();
    modules(src, "", &mut out);
    out.sort();
    out.dedup();
    out
}

/// The file of module `a::b` of the test crate at `krate`, if it has one: `a/b.rs` or
/// `a/b/mod.rs` (a module written inline in its parent, holding only children, has none).
fn module_file(krate: &Path, module: &str) -> Option<PathBuf> {
    let base = module
        .split("::")
        .fold(krate.to_path_buf(), |d, p| d.join(p));
    [base.with_extension("rs"), base.join("mod.rs")]
        .into_iter()
        .find(|p| p.is_file())
}

/// The modules of `src` with neither a spec module under `spec` nor an entry of `covered`.
fn uncovered(src: &Path, spec: &Path, covered: &[(&str, &str, &str)]) -> Vec<String> {
    src_modules(src)
        .into_iter()
        .filter(|m| module_file(spec, m).is_none())
        .filter(|m| !covered.iter().any(|c| c.0 == m))
        .collect()
}

#[test]
fn every_src_module_has_its_spec_module_or_is_covered() {
    let missing = uncovered(&root().join("src"), &root().join("tests/spec"), COVERED);
    assert!(
        missing.is_empty(),
        "modules of src/ with no spec module under tests/spec/ and no entry in COVERED \
         (tests/repository/index.rs):\n  {}\nwrite its spec module (tests/spec/a/b.rs for \
         src/a/b.rs, declared by its parent), or add (\"module\", \"crate::test::module\", \
         \"why\") to COVERED",
        missing.join("\n  ")
    );
}

#[test]
fn every_covered_entry_is_true() {
    let src = src_modules(&root().join("src"));
    let mut problems = Vec::new();
    for (module, cover, why) in COVERED {
        if !src.iter().any(|m| m == module) {
            problems.push(format!("{module}: no such module in src/ (a stale entry)"));
        }
        if module_file(&root().join("tests/spec"), module).is_some() {
            problems.push(format!(
                "{module}: has a spec module, so its entry is stale"
            ));
        }
        let (krate, path) = cover.split_once("::").unwrap_or((cover, ""));
        let dir = root().join("tests").join(krate);
        let found = if path.is_empty() {
            dir.join("main.rs").is_file() || root().join(format!("tests/{krate}.rs")).is_file()
        } else {
            module_file(&dir, path).is_some()
        };
        if !found {
            problems.push(format!("{module}: its cover {cover} is no test module"));
        }
        if why.trim().is_empty() {
            problems.push(format!("{module}: says not why"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_index_finds_a_new_module_without_a_spec() {
    // a source tree of three modules, one with a spec module, one covered, one new
    let dir = std::env::temp_dir().join(format!("pathspace-index-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for file in [
        "src/lib.rs",
        "src/scene/mod.rs",
        "src/scene/reader.rs",
        "src/film.rs",
    ] {
        std::fs::create_dir_all(dir.join(file).parent().unwrap()).unwrap();
        std::fs::write(dir.join(file), "").unwrap();
    }
    std::fs::create_dir_all(dir.join("spec")).unwrap();
    std::fs::write(dir.join("spec/scene.rs"), "").unwrap();
    let covered = [("film", "oracles::golden", "every render has one")];
    let missing = uncovered(&dir.join("src"), &dir.join("spec"), &covered);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(missing, ["scene::reader"]);
}

/// True when a file of a crate declares `mod name;` (or `mod name {`).
fn declares(file: &Path, name: &str) -> bool {
    std::fs::read_to_string(file).is_ok_and(|text| {
        text.lines().any(|l| {
            let l = l.trim_start().trim_start_matches("pub ");
            l == format!("mod {name};") || l == format!("mod {name} {{")
        })
    })
}

#[test]
fn every_test_file_is_declared() {
    let tests = root().join("tests");
    let mut undeclared = Vec::new();
    for entry in std::fs::read_dir(&tests).unwrap() {
        let krate = entry.unwrap().path();
        if !krate.join("main.rs").is_file() {
            continue;
        }
        let mut files = Vec::new();
        collect(&krate, &mut files);
        for file in files {
            let rel = file.strip_prefix(&krate).unwrap();
            if rel == Path::new("main.rs") {
                continue;
            }
            // the module's name and the folder its parent lives in
            let (name, dir) = if file.file_name().unwrap() == "mod.rs" {
                let d = file.parent().unwrap();
                (d.file_name().unwrap(), d.parent().unwrap())
            } else {
                (file.file_stem().unwrap(), file.parent().unwrap())
            };
            let name = name.to_string_lossy();
            // the parent: the folder's own file, its mod.rs, or (inline) any ancestor's file
            let mut parents = vec![dir.with_extension("rs"), dir.join("mod.rs")];
            let mut up = dir;
            while up.starts_with(&krate) {
                parents.push(up.with_extension("rs"));
                parents.push(up.join("main.rs"));
                up = up.parent().unwrap();
            }
            if !parents.iter().any(|p| p != &file && declares(p, &name)) {
                undeclared.push(file.strip_prefix(&tests).unwrap().display().to_string());
            }
        }
    }
    assert!(
        undeclared.is_empty(),
        "test files no `mod` declares (never compiled, never run):\n  {}",
        undeclared.join("\n  ")
    );
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            collect(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}
