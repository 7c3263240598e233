//! The Python binding of pathspace (`pathspace._pathspace`; the package `pathspace` wraps it).
//! Nothing here is a second renderer or a second option list: a scene is read by
//! `SceneSource` and built by `scene::build`, a render is `render::Render::run` with this
//! front end, its options are the `[render]` schema of `integrator::settings`, its statistics
//! the command line's `--json` object, its EXR the command line's.

// the command line's error (`CliError`) is returned once per call, to become a Python exception
#![allow(clippy::result_large_err)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;

use pathspace::cli::CliError;
use pathspace::image_io::{self, Image, ImageMeta};
use pathspace::integrator::settings::{RenderOptions, Spelling};
use pathspace::integrator::{IntegratorKind, RenderSettings};
use pathspace::render::run::LiveView;
use pathspace::render::session::{PassView, Preprocessed, RenderResult};
use pathspace::render::{Frontend, Outputs, Render};
use pathspace::scene::file::{self as scene_file, SceneFile};
use pathspace::scene::{SceneError, SceneSource};

pyo3::create_exception!(
    _pathspace,
    Error,
    PyValueError,
    "A scene, an option or a render refused, with the command line's message."
);

/// The error of a scene file as Python sees it: the command line's message, and the file,
/// line and key as attributes.
fn scene_error(py: Python<'_>, e: &SceneError) -> PyErr {
    let err = Error::new_err(e.to_string());
    let value = err.value(py);
    let _ = value.setattr("file", &e.file);
    let _ = value.setattr("line", e.line);
    let _ = value.setattr("key", &e.key);
    err
}

fn error(message: impl ToString) -> PyErr {
    Error::new_err(message.to_string())
}

/// A loaded scene: its source, its parsed description, the built scene and its `[render]`
/// settings. Immutable: a parameter update builds a changed copy.
#[pyclass(frozen, module = "pathspace._pathspace")]
struct Scene {
    src: SceneSource,
    desc: SceneFile,
    scene: pathspace::scene::Scene,
    settings: RenderSettings,
    resolution: Option<(u32, u32)>,
}

impl Scene {
    /// Builds `desc` (parsed from `src`) with the camera at `resolution` (`--resolution`).
    fn build(
        src: SceneSource,
        desc: SceneFile,
        resolution: Option<(u32, u32)>,
        before: Option<&Scene>,
    ) -> Result<Scene, CliError> {
        let mut scene = pathspace::scene::build::build_parsed(&src, &desc)?;
        // the [render] table is unchanged; its defaults depend on the scene's radius alone
        let settings = match before {
            Some(b) if b.scene.radius == scene.radius => b.settings.clone(),
            _ => RenderSettings::from_source(&src, scene.radius)?,
        };
        if let Some((w, h)) = resolution {
            let cam = scene
                .camera
                .as_ref()
                .ok_or_else(|| CliError::Usage("resolution needs a scene with a camera".into()))?;
            scene.camera = cam.with_resolution(w, h);
        }
        Ok(Scene {
            src,
            desc,
            scene,
            settings,
            resolution,
        })
    }

    fn load(py: Python<'_>, src: SceneSource, resolution: Option<(u32, u32)>) -> PyResult<Scene> {
        let desc = scene_file::parse(&src.text, &src.name)
            .map_err(|e| scene_error(py, &src.relocate(e)))?;
        Scene::build(src, desc, resolution, None).map_err(|e| cli_error(py, e))
    }
}

fn cli_error(py: Python<'_>, e: CliError) -> PyErr {
    match e {
        CliError::Scene(s) => scene_error(py, &s),
        e => error(e),
    }
}

/// `pathspace.load_file(path)`: a TOML scene file, or Mitsuba 3 XML by its `.xml` extension.
#[pyfunction]
#[pyo3(signature = (path, resolution=None))]
fn load_file(py: Python<'_>, path: PathBuf, resolution: Option<(u32, u32)>) -> PyResult<Scene> {
    let src = SceneSource::read(&path).map_err(|e| scene_error(py, &e))?;
    Scene::load(py, src, resolution)
}

/// `pathspace.load_string(text)`: a scene file's text (TOML), relative paths from `base_dir`.
#[pyfunction]
#[pyo3(signature = (text, name="<string>", base_dir=None, resolution=None))]
fn load_string(
    py: Python<'_>,
    text: &str,
    name: &str,
    base_dir: Option<PathBuf>,
    resolution: Option<(u32, u32)>,
) -> PyResult<Scene> {
    let mut src = SceneSource::embedded(name, text);
    if let Some(d) = base_dir {
        src.base_dir = d;
    }
    Scene::load(py, src, resolution)
}

/// The TOML text of a scene given as JSON (`load_dict`'s dictionary, the same schema).
#[pyfunction]
fn toml_of_json(json: &str) -> PyResult<String> {
    let v: toml::Value = serde_json::from_str(json).map_err(error)?;
    toml::to_string(&v).map_err(error)
}

/// A description as JSON, its f32 values in their shortest spelling (`0.1`, not the f64
/// `0.10000000149011612` of the same number).
fn description(desc: &SceneFile) -> PyResult<serde_json::Value> {
    serde_json::from_str(&serde_json::to_string(desc).map_err(error)?).map_err(error)
}

/// One step of a parameter's key path (`media.fog.sigma_s`, `lights[0].radiance`).
enum Step {
    Key(String),
    Index(usize),
}

fn steps(key: &str) -> Option<Vec<Step>> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (name, mut rest) = part.split_once('[').map_or((part, ""), |(n, r)| (n, r));
        if name.is_empty() {
            return None;
        }
        out.push(Step::Key(name.to_string()));
        while !rest.is_empty() {
            let (i, r) = rest.split_once(']')?;
            out.push(Step::Index(i.parse().ok()?));
            rest = r.strip_prefix('[').unwrap_or(r);
        }
    }
    Some(out)
}

/// The leaves of a description as key paths: numbers, numeric triples, booleans and strings
/// (`render`, the options of `render()`, left out).
fn leaves(v: &serde_json::Value, at: String, out: &mut BTreeMap<String, serde_json::Value>) {
    use serde_json::Value as V;
    match v {
        V::Object(m) => {
            for (k, x) in m {
                if at.is_empty() && k == "render" {
                    continue;
                }
                let key = if at.is_empty() {
                    k.clone()
                } else {
                    format!("{at}.{k}")
                };
                leaves(x, key, out);
            }
        }
        V::Array(a) if a.is_empty() => {}
        V::Array(a) if a.iter().all(|x| x.is_number()) => {
            out.insert(at, v.clone());
        }
        V::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                leaves(x, format!("{at}[{i}]"), out);
            }
        }
        V::Null => {}
        _ => {
            out.insert(at, v.clone());
        }
    }
}

/// Sets `key` of description `v` to `value`: the key must be one of the description (an
/// optional key it leaves out, such as `emission`, included).
fn set_at(v: &mut serde_json::Value, key: &str, value: serde_json::Value) -> Result<(), String> {
    let bad = || format!("`{key}` is no parameter of the scene (see traverse())");
    let path = steps(key).ok_or_else(bad)?;
    if matches!(path.first(), Some(Step::Key(k)) if k == "render") {
        return Err(format!(
            "`{key}`: render options are arguments of render(), not scene parameters"
        ));
    }
    let mut at = v;
    for s in &path {
        at = match s {
            Step::Key(k) => at.as_object_mut().and_then(|m| m.get_mut(k)),
            Step::Index(i) => at.as_array_mut().and_then(|a| a.get_mut(*i)),
        }
        .ok_or_else(bad)?;
    }
    *at = value;
    Ok(())
}

#[pymethods]
impl Scene {
    /// The scene's name (its file).
    #[getter]
    fn name(&self) -> &str {
        &self.src.name
    }

    /// The camera's (width, height), or None for a scene of meters only.
    #[getter]
    fn size(&self) -> Option<(u32, u32)> {
        self.scene.camera.as_ref().map(|c| (c.width, c.height))
    }

    /// The scene as a TOML scene file (a changed copy's description, which the command line
    /// renders to the same image).
    fn to_toml(&self) -> String {
        self.src.text.clone()
    }

    /// The parameters as a JSON object `{key path: value}`.
    fn parameters_json(&self) -> PyResult<String> {
        let v = description(&self.desc)?;
        let mut out = BTreeMap::new();
        leaves(&v, String::new(), &mut out);
        serde_json::to_string(&out).map_err(error)
    }

    /// A copy with the parameters of `changes` (a JSON object `{key path: value}`) replaced,
    /// built from the changed description without parsing the file again.
    fn updated(&self, py: Python<'_>, changes: &str) -> PyResult<Scene> {
        let changes: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(changes).map_err(error)?;
        let mut v = description(&self.desc)?;
        for (k, x) in &changes {
            set_at(&mut v, k, x.clone()).map_err(error)?;
        }
        let desc: SceneFile = serde_json::from_value(v).map_err(|e| {
            let keys: Vec<&str> = changes.keys().map(String::as_str).collect();
            error(format!("{}: {e}", keys.join(", ")))
        })?;
        // a changed resolution is the new one; otherwise the override stays
        let resolution = self
            .resolution
            .filter(|_| !changes.contains_key("camera.resolution"));
        let mut src = self.src.clone();
        src.text = toml::to_string(&desc).map_err(error)?;
        src.inputs = Default::default();
        Scene::build(src, desc, resolution, Some(self)).map_err(|e| cli_error(py, e))
    }

    /// Renders with the options of `options` (a JSON object of `[render]` keys) on `threads`
    /// threads (default: all cores), for `time` seconds instead of the spp if given; calls
    /// `progress(spp_done, spp_target)` after every pass. Returns the result and whether the
    /// render was interrupted (Ctrl-C, or an exception of `progress`, after the pass in flight).
    #[pyo3(signature = (options, threads=None, time=None, progress=None))]
    fn render(
        &self,
        py: Python<'_>,
        options: &str,
        threads: Option<usize>,
        time: Option<f64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<(RenderOutput, bool)> {
        let o = render_options(options)?;
        let mut settings = self.settings.clone();
        settings.apply(&o, Spelling::Key).map_err(|e| {
            let key = ["render", e.table, e.key.unwrap_or("")]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(".");
            error(format!("key `{key}`: {}", e.message))
        })?;
        if let Some(t) = time.filter(|t| !(*t > 0.0 && t.is_finite())) {
            return Err(error(format!(
                "time {t} must be a positive number of seconds"
            )));
        }
        let kind = settings.integrator;
        let mut render = Render::new(&self.scene, &self.src, kind, settings, None)
            .map_err(|e| error(CliError::from(e)))?;
        render.time = time;
        render.show = false;
        let target = time.is_none().then_some(render.settings.spp);
        run(py, &render, threads, target, progress)
    }
}

/// The options of a JSON object of `[render]` keys, through the schema; a value its type
/// refuses is named by its key, as the scene file's would be.
fn render_options(json: &str) -> PyResult<RenderOptions> {
    let given: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(json).map_err(error)?;
    serde_json::from_value(serde_json::Value::Object(given.clone())).map_err(|e| {
        let bad = given.iter().find_map(|(k, v)| {
            let one = serde_json::Map::from_iter([(k.clone(), v.clone())]);
            let e = serde_json::from_value::<RenderOptions>(one.into()).err()?;
            Some(error(format!("key `render.{k}`: {e}")))
        });
        bad.unwrap_or_else(|| error(format!("render options: {e}")))
    })
}

/// The stop flag of the renders in flight: set (to SIGINT's number) when Python sees Ctrl-C
/// or a progress callback raises; the passes stop after the one in flight.
static STOP: AtomicUsize = AtomicUsize::new(0);

const SIGINT: usize = 2;

/// The binding's part of a render: its threads, no files, a message after every pass (and,
/// with a progress callback, a wait for its answer, so that a callback that stops the render
/// stops it after that pass).
struct Binding {
    threads: Option<usize>,
    passes: mpsc::Sender<u64>,
    answers: Option<std::sync::Mutex<mpsc::Receiver<()>>>,
}

impl Frontend for Binding {
    type Error = CliError;

    fn pool(&mut self) -> Result<rayon::ThreadPool, CliError> {
        pathspace::cli::thread_pool(self.threads)
    }

    fn write(
        &self,
        _: &Render,
        _: &RenderResult,
        _: &Preprocessed,
    ) -> Result<Vec<String>, CliError> {
        Ok(Vec::new())
    }

    fn live(&self, _size: Option<(u32, u32)>) -> Option<LiveView<'_>> {
        let (tx, answers) = (self.passes.clone(), &self.answers);
        Some(Box::new(move |pass: &PassView| {
            if tx.send(pass.spp).is_ok() {
                if let Some(a) = answers {
                    let _ = a.lock().map(|a| a.recv());
                }
            }
        }))
    }

    fn stop(&self) -> Result<Option<&'static AtomicUsize>, CliError> {
        Ok(Some(&STOP))
    }
}

/// Runs `render` on another thread, the GIL released, while this one hands each pass to
/// `progress` and checks for Ctrl-C between passes.
fn run(
    py: Python<'_>,
    render: &Render,
    threads: Option<usize>,
    target: Option<u32>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(RenderOutput, bool)> {
    let (tx, mut rx) = mpsc::channel();
    let (answer, answers) = mpsc::channel();
    let answers = progress.is_some().then(|| std::sync::Mutex::new(answers));
    STOP.store(0, Ordering::SeqCst);
    let mut pending: Option<PyErr> = None;
    let outcome = std::thread::scope(|s| {
        let worker = s.spawn(move || {
            let mut f = Binding {
                threads,
                passes: tx,
                answers,
            };
            render
                .run(&Outputs::default(), &mut f)
                .map(|done| RenderOutput::new(render, done))
        });
        loop {
            let (back, msg) = py.detach(move || {
                let m = rx.recv_timeout(Duration::from_millis(50));
                (rx, m)
            });
            rx = back;
            match msg {
                Ok(done) => {
                    if let (Some(cb), None) = (&progress, &pending) {
                        if let Err(e) = cb.call1(py, (done, target)) {
                            pending = Some(e);
                            STOP.store(SIGINT, Ordering::SeqCst);
                        }
                    }
                    if pending.is_none() {
                        if let Err(e) = py.check_signals() {
                            pending = Some(e);
                            STOP.store(SIGINT, Ordering::SeqCst);
                        }
                    }
                    // the next pass starts once the stop flag says whether it may
                    let _ = answer.send(());
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if pending.is_none() {
                if let Err(e) = py.check_signals() {
                    pending = Some(e);
                    STOP.store(SIGINT, Ordering::SeqCst);
                }
            }
        }
        py.detach(|| worker.join())
    });
    let output = match outcome {
        Ok(r) => r.map_err(|e| cli_error(py, e))?,
        Err(_) => return Err(error("the render panicked")),
    };
    match pending {
        Some(e) if e.is_instance_of::<PyKeyboardInterrupt>(py) => Ok((output, true)),
        Some(e) => Err(e),
        None => {
            let stopped = output.stopped;
            Ok((output, stopped))
        }
    }
}

/// What a render produced: the image and its variance of the mean, the meters, the `--json`
/// object, the EXR header's record.
#[pyclass(frozen, module = "pathspace._pathspace")]
struct RenderOutput {
    image: Option<Image>,
    variance: Option<Image>,
    meters: Vec<(String, [f32; 3], [f32; 3], u64)>,
    stats: String,
    record: ImageMeta,
    stopped: bool,
}

impl RenderOutput {
    fn new(render: &Render, done: pathspace::render::Rendered) -> RenderOutput {
        let stats = pathspace::cli::render::json_report(render, &done).to_string();
        let record = render.record(&done.ended.result, &done.pre);
        let r = done.ended.result;
        RenderOutput {
            meters: r
                .meters
                .iter()
                .map(|m| {
                    (
                        m.name.clone(),
                        m.value.to_array(),
                        m.stderr.to_array(),
                        m.samples,
                    )
                })
                .collect(),
            image: r.image,
            variance: r.variance_of_mean,
            stats,
            record,
            stopped: done.ended.stopped_by.is_some(),
        }
    }
}

/// An image as a float32 array of H x W x 3 (row-major, top row first: the EXR's order).
fn array<'py>(py: Python<'py>, image: &Image) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
    let (h, w) = (image.height as usize, image.width as usize);
    Ok(PyArray1::from_vec(py, flat).reshape([h, w, 3])?.into_any())
}

/// An H x W x 3 array as an image.
fn image_of(a: PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let v = a.as_array();
    let shape = v.shape();
    if shape[2] != 3 {
        return Err(error(format!("an image is H x W x 3, not {shape:?}")));
    }
    let pixels = (0..shape[0])
        .flat_map(|y| (0..shape[1]).map(move |x| (y, x)))
        .map(|(y, x)| glam::Vec3::new(v[[y, x, 0]], v[[y, x, 1]], v[[y, x, 2]]))
        .collect();
    Ok(Image {
        width: shape[1] as u32,
        height: shape[0] as u32,
        pixels,
    })
}

#[pymethods]
impl RenderOutput {
    /// The image, float32 H x W x 3 (None for a scene of meters only).
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.image.as_ref().map(|i| array(py, i)).transpose()
    }

    /// The variance of each pixel's mean, float32 H x W x 3 (None for light, bdpt and mlt, whose splats land in other pixels).
    #[getter]
    fn variance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.variance.as_ref().map(|i| array(py, i)).transpose()
    }

    /// The irradiance meters: (name, value, standard error, samples).
    #[getter]
    fn meters(&self) -> Vec<(String, [f32; 3], [f32; 3], u64)> {
        self.meters.clone()
    }

    /// The command line's `--json` object, as JSON text.
    #[getter]
    fn stats_json(&self) -> &str {
        &self.stats
    }

    /// The EXR header's record of the render.
    #[getter]
    fn provenance(&self) -> BTreeMap<String, String> {
        self.record.attributes.clone()
    }

    /// Writes the EXR the command line writes (its timings left out when `reproducible`, as
    /// `--reproducible` does).
    #[pyo3(signature = (path, reproducible=false))]
    fn write(&self, path: PathBuf, reproducible: bool) -> PyResult<()> {
        let image = self
            .image
            .as_ref()
            .ok_or_else(|| error("the scene has no camera: no image to write"))?;
        let mut meta = self.record.clone();
        if reproducible {
            for key in pathspace::render::provenance::TIMING_KEYS {
                meta.attributes.remove(key);
            }
        }
        image_io::check_output(&path, "exr").map_err(error)?;
        image_io::write_exr(&path, image, &meta).map_err(error)
    }
}

/// The error metrics of image `a` against the reference `b` (`pathspace diff --json`).
#[pyfunction]
fn diff(
    a: PyReadonlyArray3<'_, f32>,
    b: PyReadonlyArray3<'_, f32>,
) -> PyResult<BTreeMap<String, f64>> {
    let (a, b) = (image_of(a)?, image_of(b)?);
    let m = pathspace::measure::metrics::compare(&a, &b).map_err(error)?;
    Ok(BTreeMap::from([
        ("rmse".to_string(), m.rmse),
        ("relmse".to_string(), m.relmse),
        ("max_abs".to_string(), m.max_abs),
        ("max_f32_steps".to_string(), m.max_steps as f64),
    ]))
}

/// An equal-time convergence study (`pathspace converge`) of `integrators` on `scene` against
/// `reference`: one row per integrator, run and checkpoint.
#[pyfunction]
#[pyo3(signature = (scene, reference, integrators, budget, checkpoints=8, runs=1, seed=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn converge(
    py: Python<'_>,
    scene: &Scene,
    reference: PyReadonlyArray3<'_, f32>,
    integrators: Vec<String>,
    budget: f64,
    checkpoints: usize,
    runs: usize,
    seed: Option<u64>,
    threads: Option<usize>,
) -> PyResult<Vec<BTreeMap<String, Py<PyAny>>>> {
    use pathspace::measure::convergence::{self, ConvergeConfig};
    let reference = image_of(reference)?;
    let kinds = integrators
        .iter()
        .map(|k| IntegratorKind::parse(k))
        .collect::<Result<Vec<_>, _>>()
        .map_err(error)?;
    if runs == 0 {
        return Err(error("runs must be at least 1"));
    }
    let config = ConvergeConfig {
        budget,
        checkpoints,
        runs,
        seed: seed.unwrap_or(scene.settings.seed),
        max_depth: scene.settings.max_depth,
        shard: None,
    };
    let pool = pathspace::cli::thread_pool(threads).map_err(error)?;
    let rows = py
        .detach(|| {
            pool.install(|| {
                convergence::converge(
                    &scene.scene,
                    &scene.src,
                    &scene.settings,
                    &reference,
                    &kinds,
                    &config,
                    &mut |_| {},
                )
            })
        })
        .map_err(error)?;
    rows.into_iter()
        .map(|r| {
            let mut m = BTreeMap::new();
            m.insert(
                "integrator".into(),
                r.integrator.into_pyobject(py)?.into_any().unbind(),
            );
            m.insert("run".into(), r.run.into_pyobject(py)?.into_any().unbind());
            m.insert(
                "checkpoint".into(),
                r.checkpoint.into_pyobject(py)?.into_any().unbind(),
            );
            m.insert(
                "seconds".into(),
                r.seconds.into_pyobject(py)?.into_any().unbind(),
            );
            m.insert(
                "samples".into(),
                r.samples.into_pyobject(py)?.into_any().unbind(),
            );
            m.insert("rmse".into(), r.rmse.into_pyobject(py)?.into_any().unbind());
            m.insert(
                "relmse".into(),
                r.relmse.into_pyobject(py)?.into_any().unbind(),
            );
            m.insert(
                "efficiency".into(),
                r.efficiency.into_pyobject(py)?.into_any().unbind(),
            );
            Ok(m)
        })
        .collect()
}

/// Reads an EXR written by pathspace (or another renderer): its R, G, B as H x W x 3 and its
/// header's text attributes.
#[pyfunction]
fn read_exr<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyAny>, BTreeMap<String, String>)> {
    let (image, meta) = image_io::read_exr(&path).map_err(error)?;
    Ok((array(py, &image)?, meta.attributes))
}

/// The integrators' names, from the registry.
#[pyfunction]
fn integrators() -> Vec<&'static str> {
    IntegratorKind::ALL.iter().map(|k| k.name()).collect()
}

#[pymodule]
fn _pathspace(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Scene>()?;
    m.add_class::<RenderOutput>()?;
    m.add_function(wrap_pyfunction!(load_file, m)?)?;
    m.add_function(wrap_pyfunction!(load_string, m)?)?;
    m.add_function(wrap_pyfunction!(toml_of_json, m)?)?;
    m.add_function(wrap_pyfunction!(diff, m)?)?;
    m.add_function(wrap_pyfunction!(converge, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(integrators, m)?)?;
    Ok(())
}
