//! Integrators and the render loop they share: passes of samples over image tiles (in parallel
//! with rayon) and over irradiance meters, with every random stream derived from the seed and
//! the pixel (or meter chunk) and pass index, so the image is bit-identical whatever the thread
//! count.
//! Book: "The Neumann series and the path tracer" (path), "Measuring a renderer" (statistics),
//! "Sequential Monte Carlo adaptation" (smc: records merged between passes in tile order).

pub mod bdpt;
pub mod mixing;
pub mod mlt;
pub mod mmlt;
pub mod path;
pub mod pssmlt;
pub mod reach;
pub mod settings;
pub mod smc;

pub use settings::RenderSettings;

use rayon::prelude::*;

use crate::film::{Film, FilterBlock, PixelFilter};
use crate::math::{sampler, Sampler};
use crate::path::{LocalSampling, PLAIN};
use crate::scene::{Camera, Scene};
use crate::spectrum::Rgb;

/// Declares the integrators: one line each (its doc, variant, name, and the [`Facts`] its
/// module declares), from which the enum (an option value like the others, see
/// [`crate::conventions::OptionValue`]), [`IntegratorKind::ALL`], [`IntegratorKind::name`]
/// and [`IntegratorKind::facts`] are generated, so that adding an integrator is its module plus
/// one registration line in the invocation below.
macro_rules! integrators {
    ($($(#[doc = $doc:literal])* $variant:ident = $name:literal => $facts:expr,)*) => {
        /// The integrators a user can name (`--integrator`, `[render] integrator`).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub enum IntegratorKind {
            $($(#[doc = $doc])* #[value(name = $name)] $variant,)*
        }

        impl IntegratorKind {
            /// Every integrator, in registration order.
            pub const ALL: &'static [IntegratorKind] = &[$(IntegratorKind::$variant),*];

            /// The name `--integrator` and `[render] integrator` take.
            pub fn name(self) -> &'static str {
                match self {
                    $(IntegratorKind::$variant => $name,)*
                }
            }

            /// What the integrator's module declares it is (how it is prepared, its memory,
            /// its shard split, what it checks before a render).
            pub fn facts(self) -> &'static dyn Facts {
                match self {
                    $(IntegratorKind::$variant => $facts,)*
                }
            }
        }
    };
}

// The registration point: one line per integrator.
integrators! {
    /// Volumetric path tracing with next-event estimation and MIS.
    Path = "path" => &path::PathFacts,
    /// Light tracing: light subpaths connected to the sensor (t = 1), splatted.
    Light = "light" => &bdpt::BdptFacts(bdpt::Strategies::LightTracing),
    /// Bidirectional path tracing with MIS over all (s, t).
    Bdpt = "bdpt" => &bdpt::BdptFacts(bdpt::Strategies::All),
    /// Sequential Monte Carlo adaptation with a B-spline radiance cache (Pegoraro et al. 2008).
    Smc = "smc" => &smc::SmcFacts,
    /// Metropolis light transport (film-wide; `spp` counts mutations per pixel).
    Mlt = "mlt" => &mlt::MltFacts,
    /// Primary-sample-space MLT over BDPT samples (Kelemen et al. 2002).
    Pssmlt = "pssmlt" => &pssmlt::PssmltFacts,
    /// Multiplexed MLT: one BDPT strategy per chain state (Hachisuka et al. 2014).
    Mmlt = "mmlt" => &mmlt::MmltFacts,
}

crate::option_value!(IntegratorKind, "integrator");

impl IntegratorKind {
    /// The integrator named `s`, or the error that lists the names.
    pub fn parse(s: &str) -> Result<Self, IntegratorError> {
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
                IntegratorError::Unknown(s.to_string(), names.join(", "))
            })
    }

    /// Builds the integrator from the setup, or says why it refuses the scene or its settings.
    pub fn prepare<'t>(
        self,
        setup: &Setup<'_, 't>,
    ) -> Result<Box<dyn Integrator + 't>, IntegratorError> {
        check_emitting_media(self, setup.scene)?;
        self.facts().prepare(setup)
    }

    /// Whether the integrator samples light start points (and so can use the adjoint image).
    pub fn samples_light_starts(self) -> bool {
        self.facts().samples_light_starts()
    }

    /// Whether the integrator samples with the guide ([`Facts::takes_guide`]).
    pub fn takes_guide(self) -> bool {
        self.facts().takes_guide()
    }

    /// The names of the integrators whose facts say `yes`, for a message (`path or smc`).
    pub fn names_where(yes: impl Fn(&dyn Facts) -> bool) -> String {
        let names: Vec<&str> = Self::ALL
            .iter()
            .filter(|k| yes(k.facts()))
            .map(|k| k.name())
            .collect();
        match names.split_last() {
            Some((last, [])) => last.to_string(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        }
    }
}

/// An option that only the integrators that declare it take ([`Facts::takes`]): a front end
/// refuses it for the others by asking their facts, never by naming them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OwnOption {
    /// The `[render.smc]` table and its flags.
    Smc,
    /// `distance = "equiangular-mis"` (equiangular sampling on every ray, by MIS).
    EquiangularDistance,
    /// `light_selection` (how next-event estimation picks a light).
    LightSelection,
    /// `light_point` (how next-event estimation draws a point on an area light).
    LightPoint,
    /// `halo_cone` (scattering directions drawn in part toward lights' halos).
    HaloCone,
    /// The images of its sampling techniques one by one (`--strategy-images`).
    StrategyImages,
    /// `pixel_samples` (it draws each camera sample's film position in its pixel).
    PixelSamples,
    /// `mis_heuristic` (it weights several strategies of one path).
    MisHeuristic,
}

/// Refuses a scene with an emitting medium for an integrator that cannot collect its light,
/// naming the medium and the reason (never a silent image without the glow).
pub fn check_emitting_media(kind: IntegratorKind, scene: &Scene) -> Result<(), IntegratorError> {
    let Some(why) = kind.facts().emitting_media_refusal() else {
        return Ok(());
    };
    match scene.media.iter().position(crate::medium::Medium::emits) {
        Some(i) => Err(IntegratorError::Refused(format!(
            "`{}` cannot render the emitting medium `{}` (emission, L_e,V0 of eq. 1): {why}; render it with `path`",
            kind.name(),
            scene.medium_names[i]
        ))),
        None => Ok(()),
    }
}

/// Why an integrator cannot render: the errors of the integrator layer, with the messages the
/// command line prints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IntegratorError {
    /// A name that is no integrator (the name, the available ones).
    #[error("unknown integrator `{0}` (available: {1})")]
    Unknown(String, String),
    /// The integrator refuses the scene or its settings, and says why.
    #[error("{0}")]
    Refused(String),
}

/// What a checkpoint keeps of an integrator besides the film and the meters: bytes only the
/// integrator reads ([`Integrator::checkpoint_state`]), `None` when the film, the meters and the
/// pass index are all of it. The render layer's checkpoint stores them without knowing them.
pub type IntegratorState = Option<Vec<u8>>;

impl From<String> for IntegratorError {
    fn from(reason: String) -> Self {
        IntegratorError::Refused(reason)
    }
}

/// The adjoint image's pre-pass refuses the scene or its settings (a preprocessing stage of
/// the render session).
impl From<crate::enlightened::AdjointError> for IntegratorError {
    fn from(e: crate::enlightened::AdjointError) -> Self {
        IntegratorError::Refused(e.to_string())
    }
}

impl From<IntegratorError> for String {
    fn from(e: IntegratorError) -> Self {
        e.to_string()
    }
}

/// What an integrator is prepared from: the scene, the local-sampling technique (plain, or the
/// enlightened one the preprocessing stages built), its render settings, the seed and the depth
/// limit (one struct, so that a new setting reaches every integrator without a new argument).
/// The technique may outlive the settings: the integrator keeps it, not them.
#[derive(Clone, Copy)]
pub struct Setup<'s, 't> {
    pub scene: &'s Scene,
    pub technique: &'t dyn LocalSampling,
    pub settings: &'s RenderSettings,
    pub seed: u64,
    pub max_depth: Option<u32>,
}

/// What an integrator is before it is prepared, declared by its module and registered with
/// its name (`integrators!`): how it is built, what the render layer must know of it to check
/// a render, estimate its memory and split it into shards. The render layer asks these, never
/// the integrator's kind.
pub trait Facts: Sync {
    /// Builds the integrator from the setup, or says why it refuses the scene or its settings.
    fn prepare<'t>(
        &self,
        setup: &Setup<'_, 't>,
    ) -> Result<Box<dyn Integrator + 't>, IntegratorError>;

    /// Whether it samples light start points (and so can use the adjoint image).
    fn samples_light_starts(&self) -> bool {
        false
    }

    /// Whether it samples with the guide (`--guide`, `[render.guide]`): its walks draw their
    /// scattering directions, and its MIS weights evaluate them, through the technique. By
    /// default the integrators that sample light start points (their subpaths are the
    /// technique's from both ends).
    fn takes_guide(&self) -> bool {
        self.samples_light_starts()
    }

    /// Why it cannot render a scene with an emitting medium (L_e,V0 of eq. 1), or `None` when
    /// it collects that emission ([`check_emitting_media`] names the medium).
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        Some("it does not collect light emitted by a medium")
    }

    /// Refuses, before any work or memory, a scene or settings it cannot render (MLT's
    /// scene, SMC's march length).
    fn check(&self, _case: &Case) -> Result<(), IntegratorError> {
        Ok(())
    }

    /// The light paths its techniques cannot sample, of which the render warns
    /// ([`reach::unreachable_paths`]).
    fn unreachable(&self) -> reach::Unreachable {
        reach::Unreachable::Nothing
    }

    /// Warnings of its own about the scene with these settings, given once before the work.
    fn warnings(&self, _case: &Case) -> Vec<String> {
        Vec::new()
    }

    /// What one sample leaves in a pass until the pass is merged (for the memory estimate).
    fn pass_footprint(&self, case: &Case) -> PassFootprint;

    /// Its structures besides the film and a pass's results: (name, bytes) for the memory
    /// estimate (SMC's cache, MLT's chains).
    fn memory_parts(&self, _case: &Case) -> Vec<(&'static str, u64)> {
        Vec::new()
    }

    /// How a render by it is split into shards.
    fn shard_split(&self) -> ShardSplit {
        ShardSplit::Passes
    }

    /// Its chain count, which a [`ShardSplit::IndependentChains`] split shares out.
    fn chains(&self) -> Option<ChainCount> {
        None
    }

    /// The `--json` key of its [`Statistics`] (null in the other integrators' output), if it
    /// reports any.
    fn statistics_key(&self) -> Option<&'static str> {
        None
    }

    /// Whether it takes `option`, one of the options only some integrators take.
    fn takes(&self, _option: OwnOption) -> bool {
        false
    }

    /// Whether the film's per-pixel variance estimates the image's: each sample adds to its
    /// own pixel only (not where samples splat into other pixels, as light tracing's and MLT's
    /// do, whose variance the film does not record).
    fn pixel_variance(&self) -> bool {
        true
    }

    /// What to tell a user whose image has pixels with a negative estimate, besides that the
    /// estimator has not converged there (SMC's control variates), if anything.
    fn negative_pixels_hint(&self) -> Option<&'static str> {
        None
    }
}

/// What [`Facts`] are asked about before a render: the scene and the render's settings (the
/// integrator reads its own table of them, as from a [`Setup`]).
#[derive(Clone, Copy)]
pub struct Case<'s> {
    pub scene: &'s Scene,
    pub settings: &'s RenderSettings,
}

/// What a pass of an integrator holds per sample until it is merged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassFootprint {
    /// Whether the pass keeps per-pixel tile results (false for film-wide passes).
    pub tiles: bool,
    /// Bytes a sample deposits besides its value (splats, SMC's records).
    pub bytes_per_sample: u64,
}

/// One splat's bytes: film point and value.
pub const SPLAT_BYTES: u64 = std::mem::size_of::<(glam::Vec2, glam::Vec3)>() as u64;

/// How a render is split into shards (the render layer's `shard` holds the arithmetic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardSplit {
    /// Each shard renders contiguous passes of the same seed.
    Passes,
    /// Each shard is an independent run with a seed of its own, a share of the chains and of
    /// the mutations (MLT).
    IndependentChains,
    /// Refused: a pass learns from every earlier pass (SMC's cache); the integrator's name.
    Refused(&'static str),
}

/// An integrator's chain count: the flag that sets it and where the settings hold it.
#[derive(Clone, Copy)]
pub struct ChainCount {
    pub flag: &'static str,
    pub get: fn(&RenderSettings) -> u32,
    pub set: fn(&mut RenderSettings, u32),
}

/// Per-thread storage of a tile or meter chunk, reused from sample to sample so that no
/// sample allocates: the integrator's own (the walks of the bidirectional methods, SMC's path
/// links and records) and the splats the samples deposit on the film.
#[derive(Default)]
pub struct Scratch {
    pub own: Own,
    pub splats: Vec<Splat>,
}

/// A splat on the film: film point and value.
pub type Splat = (glam::Vec2, Rgb);

/// An integrator's own per-thread storage, of a type only it knows, made on first use.
pub struct Own(Box<dyn std::any::Any + Send>);

impl Default for Own {
    fn default() -> Self {
        Own(Box::new(()))
    }
}

impl Own {
    /// The storage as a `T` (a fresh one the first time a tile or chunk asks).
    pub fn get<T: Default + Send + 'static>(&mut self) -> &mut T {
        if !self.0.is::<T>() {
            self.0 = Box::new(T::default());
        }
        self.0
            .downcast_mut()
            .expect("the storage was just made a T")
    }
}

/// What a tile or meter chunk leaves for the end of the pass (SMC's records), of a type only
/// the integrator knows.
pub type Deposit = Box<dyn std::any::Any + Send>;

/// What an integrator reports after its passes, serialized by the integrator itself: `--json`
/// shows `json` under its [`Facts::statistics_key`], the summary prints the lines.
#[derive(Clone, Debug, Default)]
pub struct Statistics {
    /// The value `--json` shows (SMC's structure, MLT's b and mutation counts).
    pub json: Option<serde_json::Value>,
    /// Summary lines printed after the integrator's line, before the meters'.
    pub lines: Vec<String>,
    /// Summary lines printed after the meters'.
    pub closing: Vec<String>,
    /// Warnings the front end prints on stderr (MCMC chains that have not mixed).
    pub warnings: Vec<String>,
    /// Attributes the image's header records (name, value): the chains' mixing diagnostics.
    pub header: Vec<(String, String)>,
}

/// An integrator as the render loop sees it: one sample of the camera's film or of a meter,
/// drawn from the sampler it is handed (streams `Sampler::new(seed, pixel, pass)`, so images
/// do not depend on threads), and the hooks of a pass. The tile and meter loops are written
/// once, in [`Renderer::pass`]; every method is read-only during a pass (SMC's records are
/// merged in [`Integrator::end_pass`], Pegoraro et al.'s fixed predicates).
pub trait Integrator: Send + Sync {
    /// Its name in `--json`, the EXR metadata and the summary (`smc (is1_cv2, march)`).
    fn label(&self) -> String;

    /// One camera sample through film point `raster`: the pixel's value (splats go to
    /// `scratch.splats`, what the pass keeps to the integrator's `scratch.own`). Unused by a
    /// film-wide integrator ([`Integrator::film_pass`]), which renders no tiles.
    fn camera_sample(
        &self,
        _scene: &Scene,
        _cam: &Camera,
        _raster: glam::Vec2,
        _sampler: &mut Sampler,
        _scratch: &mut Scratch,
    ) -> Rgb {
        Rgb::ZERO
    }

    /// One sample of meter `meter`'s mean irradiance. Unused by a film-wide integrator, which
    /// renders the camera's image only.
    fn meter_sample(
        &self,
        _scene: &Scene,
        _meter: u32,
        _sampler: &mut Sampler,
        _scratch: &mut Scratch,
    ) -> Rgb {
        Rgb::ZERO
    }

    /// The camera's direct view of delta lights that the pass adds, one splat per light
    /// standing for one camera sample, drawn from `sampler` (the path tracer and SMC; BDPT's
    /// (1, 1) strategy does it per sample): empty when the samples see them.
    fn delta_light_view(&self, _scene: &Scene, _sampler: &mut Sampler) -> Vec<Splat> {
        Vec::new()
    }

    /// A film-wide pass instead of tiles and meters (MLT: `spp` mutations per pixel over all
    /// chains); returns the paths traced, `None` for the tile loop.
    fn film_pass(&mut self, _scene: &Scene, _film: &mut Film, _spp: u32) -> Option<u64> {
        None
    }

    /// What a finished tile or meter chunk leaves for the end of the pass, taken from its
    /// storage (SMC's records); `None` when the integrator keeps nothing.
    fn deposit(&self, _own: &mut Own) -> Option<Deposit> {
        None
    }

    /// After a pass: the deposits of its tiles, then of its meter chunks, in order.
    fn end_pass(&mut self, _deposits: &[Deposit]) {}

    /// The statistics the integrator reports.
    fn statistics(&self) -> Statistics {
        Statistics::default()
    }

    /// What a checkpoint keeps of the integrator besides the film and the meters, serialized
    /// by the integrator (SMC's structure, which the passes so far have refined).
    fn checkpoint_state(&self) -> IntegratorState {
        None
    }

    /// Takes back a checkpoint's [`Integrator::checkpoint_state`], or says why it cannot (the
    /// state of another integrator, or one that does not hold together).
    fn restore_state(&mut self, state: Option<&[u8]>) -> Result<(), &'static str> {
        match state {
            None => Ok(()),
            Some(_) => Err("it holds another integrator's state"),
        }
    }

    /// The work this integrator does once before its first pass (MLT's bootstrap pre-pass and
    /// the chains' seed paths), named for the user; `None` when there is none left.
    fn pending_stage(&self) -> Option<String> {
        None
    }

    /// Does the [`Integrator::pending_stage`] now, so that the session can name and time it
    /// (otherwise the first pass does it).
    fn run_stage(&mut self, _scene: &Scene) {}

    /// Whether a checkpoint continues this integrator's run exactly. MLT's chains are not
    /// saved: a resumed MLT render is an independent run merged by sample count.
    fn resumes_exactly(&self) -> bool {
        true
    }

    /// Its contributions split by sampling technique, each weighted as in the image so that
    /// they sum to it (BDPT's (s, t) strategies, a user's favourite debugging view): one pass
    /// `pass` of `spp` samples per pixel with the render loop's streams, techniques with at
    /// most `max_depth_shown` scattering vertices; `None` when it has no techniques to show.
    fn technique_images(
        &self,
        _scene: &Scene,
        _seed: u64,
        _pass: u64,
        _spp: u32,
        _max_depth_shown: u32,
    ) -> Option<std::collections::BTreeMap<(usize, usize), Film>> {
        None
    }

    /// The integrator as [`std::any::Any`], for a program that knows its type (a test reading
    /// SMC's structure through [`Renderer::engine`]); `None` for one that borrows the scene.
    fn as_any(&self) -> Option<&dyn std::any::Any> {
        None
    }
}

/// Side of a square image tile.
pub const TILE: u32 = 16;
/// Meter samples per parallel work item.
pub const METER_CHUNK: u64 = 1024;
/// The stream of the path tracer's direct view of delta lights (apart from every pixel's).
const DELTA_VIEW_STREAM: u64 = u64::MAX - 1;
/// Salt that keeps meter streams apart from pixel streams of the same index.
const METER_STREAM_SALT: u64 = 0x6D65_7465_7200_0000;

/// A meter's running statistics.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct MeterAccum {
    pub sum: [f64; 3],
    pub sum_sq: [f64; 3],
    pub samples: u64,
}

/// A meter's estimate with its standard error.
#[derive(Clone, Debug)]
pub struct MeterEstimate {
    pub name: String,
    pub value: Rgb,
    pub stderr: Rgb,
    pub samples: u64,
}

impl MeterAccum {
    pub fn estimate(&self, name: &str) -> MeterEstimate {
        let n = self.samples.max(1) as f64;
        let mut v = [0.0f32; 3];
        let mut e = [0.0f32; 3];
        for c in 0..3 {
            let mean = self.sum[c] / n;
            let var = if self.samples > 1 {
                ((self.sum_sq[c] / n - mean * mean) * n / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            v[c] = mean as f32;
            e[c] = (var / n).sqrt() as f32;
        }
        MeterEstimate {
            name: name.to_string(),
            value: Rgb::from_array(v),
            stderr: Rgb::from_array(e),
            samples: self.samples,
        }
    }
}

/// Where in its pixel each camera sample's film position lies (`[render] pixel_samples`,
/// `--pixel-samples`; book: "Measuring a renderer", section "Stratified film positions").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum PixelSamples {
    /// The pixel's points of a (0, 2)-sequence, digitally shifted per pixel and seed: the
    /// first 2^m samples, and each 2^m after them, cover the pixel's 2^m elementary intervals
    /// of area 2^-m once each.
    #[default]
    Stratified,
    /// Independent uniform positions from the pixel's PCG streams: the variance the film
    /// records per pixel then estimates the variance of the pixel's mean, where stratified
    /// positions make it overstate that variance across edges.
    Independent,
}

crate::option_value!(PixelSamples, "pixel samples");

/// The offset in its pixel of a pixel's sample `k`: the pixel's stratified point `k` (the
/// sequence starts again past 2^32 samples) or two numbers of its stream. The two are drawn
/// in both modes, so that the rest of the sample's stream does not depend on the mode.
#[inline]
fn film_offset(stratified: bool, k: u64, shift: u64, sampler: &mut Sampler) -> glam::Vec2 {
    let uniform = sampler.next_2d();
    if stratified {
        sampler::stratified_point(k as u32, shift)
    } else {
        uniform
    }
}

/// Accumulates passes of an integrator over the camera film and the meters.
pub struct Renderer<'a> {
    pub scene: &'a Scene,
    pub kind: IntegratorKind,
    pub seed: u64,
    /// The depth limit the integrator was prepared with.
    pub max_depth: Option<u32>,
    /// The local-sampling technique the integrator was prepared with.
    technique: &'a dyn LocalSampling,
    /// The integrator (replaceable before the first pass, e.g. by a BDPT of one strategy).
    pub integrator: Box<dyn Integrator + 'a>,
    pub film: Option<Film>,
    pub meters: Vec<MeterAccum>,
    /// Passes done so far (each pass has its own random streams).
    pub passes: u64,
    /// Samples per pixel of the passes before the next one, counted from the render's first
    /// pass (a shard's or a resumed render's earlier passes included): the index of the
    /// next pass's first stratified film position ([`PixelSamples::Stratified`]).
    pub samples: u64,
    /// How each camera sample's film position is drawn.
    pub pixel_samples: PixelSamples,
    /// Samples that came out NaN or infinite and were dropped (counted as zero).
    pub nan_count: u64,
    /// Camera paths plus meter paths traced.
    pub paths: u64,
    /// Meter samples per pixel sample.
    pub meter_samples: u64,
}

/// One tile's results: its camera samples ([`TileOut`]), splats, its NaN count and its deposit.
type TileResult = (TileOut, Vec<Splat>, u64, Option<Deposit>);

/// A tile's camera samples: with the box, (pixel index, sum, sum of squares) per pixel; with
/// another filter, the block of the tile and its margin the samples spread over.
enum TileOut {
    Box(Vec<(usize, [f64; 3], [f64; 3])>),
    Filtered(FilterBlock),
}

impl TileOut {
    fn new(
        filter: PixelFilter,
        size: (u32, u32),
        xs: std::ops::Range<u32>,
        ys: std::ops::Range<u32>,
    ) -> Self {
        if filter.is_box() {
            TileOut::Box(Vec::with_capacity((TILE * TILE) as usize))
        } else {
            TileOut::Filtered(FilterBlock::new(filter, size, xs, ys))
        }
    }
}

impl<'a> Renderer<'a> {
    /// A renderer of `scene` with integrator `kind` and the default render settings.
    ///
    /// # Panics
    /// If the integrator refuses the scene ([`Renderer::try_new`] returns the reason instead:
    /// use it for scenes a user wrote).
    pub fn new(scene: &'a Scene, kind: IntegratorKind, seed: u64, max_depth: Option<u32>) -> Self {
        Self::try_new(scene, kind, seed, max_depth).unwrap_or_else(|e| panic!("{e}"))
    }

    /// A renderer of `scene` with integrator `kind` and the default render settings, or the
    /// reason the integrator refuses the scene (e.g. MLT without a camera).
    pub fn try_new(
        scene: &'a Scene,
        kind: IntegratorKind,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, IntegratorError> {
        Self::try_with(scene, &PLAIN, kind, seed, max_depth)
    }

    /// [`Renderer::try_new`] sampling with `technique` (the enlightened one, built by
    /// `enlightened::Enlightened` from the scene) instead of the plain one.
    pub fn try_with(
        scene: &'a Scene,
        technique: &'a dyn LocalSampling,
        kind: IntegratorKind,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, IntegratorError> {
        let settings = RenderSettings::for_scene(scene);
        let setup = Setup {
            scene,
            technique,
            settings: &settings,
            seed,
            max_depth,
        };
        Self::assemble(scene, kind, &setup)
    }

    /// A renderer with integrator `kind` prepared from `setup` (the scene file's settings),
    /// or the reason the integrator refuses the scene or the settings.
    pub fn prepared(kind: IntegratorKind, setup: &Setup<'a, 'a>) -> Result<Self, IntegratorError> {
        Self::assemble(setup.scene, kind, setup)
    }

    /// The renderer of `scene` (which is `setup.scene`, borrowed for the renderer's life).
    fn assemble(
        scene: &'a Scene,
        kind: IntegratorKind,
        setup: &Setup<'_, 'a>,
    ) -> Result<Self, IntegratorError> {
        Ok(Renderer {
            scene,
            kind,
            seed: setup.seed,
            max_depth: setup.max_depth,
            technique: setup.technique,
            integrator: kind.prepare(setup)?,
            film: scene
                .camera
                .as_ref()
                .map(|c| Film::with_filter(c.width, c.height, c.filter)),
            meters: vec![MeterAccum::default(); scene.sensors.len()],
            passes: 0,
            samples: 0,
            pixel_samples: setup.settings.pixel_samples,
            nan_count: 0,
            paths: 0,
            meter_samples: setup.settings.meter_samples as u64,
        })
    }

    /// Prepares the integrator again with `settings` (before the first pass; the seed, depth
    /// limit and technique stay): how a program that builds its own renderer changes an
    /// integrator's options, e.g. SMC's; an error for settings the integrator refuses.
    pub fn with_settings(mut self, settings: &RenderSettings) -> Result<Self, IntegratorError> {
        let setup = Setup {
            scene: self.scene,
            technique: self.technique,
            settings,
            seed: self.seed,
            max_depth: self.max_depth,
        };
        self.integrator = self.kind.prepare(&setup)?;
        Ok(self)
    }

    /// The integrator as its own type `T`, if it is one (a test reading SMC's structure).
    pub fn engine<T: 'static>(&self) -> Option<&T> {
        self.integrator.as_any()?.downcast_ref()
    }

    /// Samples per pixel so far.
    pub fn spp(&self) -> u64 {
        self.film.as_ref().map_or(0, |f| f.spp)
    }

    /// Renders one pass of `spp` samples per pixel (and `spp * meter_samples` per meter).
    /// `on_tile` is called after each finished tile (progress bars).
    pub fn pass(&mut self, spp: u32, on_tile: &(dyn Fn() + Sync)) {
        let pass = self.passes;
        self.passes += 1;
        let first_sample = self.samples;
        self.samples += spp as u64;
        if let Some(film) = self.film.as_mut() {
            if let Some(paths) = self.integrator.film_pass(self.scene, film, spp) {
                self.paths += paths;
                on_tile();
                return;
            }
        }
        let mut records = self.film_tiles(spp, (pass, first_sample), on_tile);
        for mi in 0..self.scene.sensors.len() {
            records.extend(self.meter_chunks(mi, spp, pass));
        }
        // the pass's deposits, in tile then meter-chunk order (SMC's records refine the
        // structure for the next pass [PWP08 Fig. 2 lines 13-14])
        self.integrator.end_pass(&records);
    }

    /// The camera's part of a pass: tiles in parallel, every pixel's stream
    /// `Sampler::new(seed, pixel, pass)`, results added in tile order; the tiles' deposits.
    /// With stratified pixel samples, the pass's film positions in each pixel are the points
    /// `first_sample..first_sample + spp` of the pixel's shifted (0, 2)-sequence.
    fn film_tiles(
        &mut self,
        spp: u32,
        (pass, first_sample): (u64, u64),
        on_tile: &(dyn Fn() + Sync),
    ) -> Vec<Deposit> {
        let scene = self.scene;
        let (Some(film), Some(cam)) = (self.film.as_mut(), scene.camera.as_ref()) else {
            return Vec::new();
        };
        let integrator = self.integrator.as_ref();
        let seed = self.seed;
        let (w, h) = (cam.width, cam.height);
        let tiles_x = w.div_ceil(TILE);
        let tiles_y = h.div_ceil(TILE);
        let filter = film.filter;
        // an integrator that reads no film position (light tracing) keeps its streams' own
        let stratified = self.pixel_samples == PixelSamples::Stratified
            && self.kind.facts().takes(OwnOption::PixelSamples);
        let results: Vec<TileResult> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|t| {
                let (tx, ty) = (t % tiles_x, t / tiles_x);
                let (xs, ys) = (
                    tx * TILE..((tx + 1) * TILE).min(w),
                    ty * TILE..((ty + 1) * TILE).min(h),
                );
                let mut out = TileOut::new(filter, (w, h), xs.clone(), ys.clone());
                let mut scratch = Scratch::default();
                let mut nans = 0u64;
                for y in ys {
                    for x in xs.clone() {
                        let index = (y * w + x) as usize;
                        let mut sampler = Sampler::new(seed, index as u64, pass);
                        let shift = sampler::film_shift(seed, index as u64);
                        let mut sum = [0.0f64; 3];
                        let mut sum_sq = [0.0f64; 3];
                        for j in 0..spp as u64 {
                            let k = first_sample + j;
                            let offset = film_offset(stratified, k, shift, &mut sampler);
                            let raster = glam::Vec2::new(x as f32, y as f32) + offset;
                            let first_splat = scratch.splats.len();
                            let l = integrator.camera_sample(
                                scene,
                                cam,
                                raster,
                                &mut sampler,
                                &mut scratch,
                            );
                            if !l.is_finite()
                                || scratch.splats[first_splat..]
                                    .iter()
                                    .any(|s| !s.1.is_finite())
                            {
                                nans += 1;
                                scratch.splats.truncate(first_splat);
                                continue;
                            }
                            if let TileOut::Filtered(block) = &mut out {
                                block.put(filter, raster, l);
                                continue;
                            }
                            for c in 0..3 {
                                let v = l[c] as f64;
                                sum[c] += v;
                                sum_sq[c] += v * v;
                            }
                        }
                        if let TileOut::Box(pixels) = &mut out {
                            pixels.push((index, sum, sum_sq));
                        }
                    }
                }
                on_tile();
                let deposit = integrator.deposit(&mut scratch.own);
                (out, scratch.splats, nans, deposit)
            })
            .collect();
        let mut records = Vec::with_capacity(results.len());
        for (out, splats, nans, tile_deposit) in results {
            records.extend(tile_deposit);
            self.nan_count += nans;
            match out {
                TileOut::Box(pixels) => {
                    for (i, s, q) in pixels {
                        film.add_pixel(i, s, q);
                    }
                }
                TileOut::Filtered(block) => film.add_block(&block),
            }
            for (r, l) in splats {
                film.add_splat(r, l);
            }
        }
        if !filter.is_box() {
            film.end_pass();
        }
        let samples = (w * h) as u64 * spp as u64;
        // the direct image of delta lights, one splat per light standing for the pass's camera
        // samples, from a stream of its own
        let mut sampler = Sampler::new(seed, DELTA_VIEW_STREAM, pass);
        for (raster, l) in integrator.delta_light_view(scene, &mut sampler) {
            film.add_splat(raster, l * samples as f32);
        }
        film.splat_count += samples;
        film.spp += spp as u64;
        self.paths += (w * h) as u64 * spp as u64;
        records
    }

    /// Meter `mi`'s part of a pass: chunks of [`METER_CHUNK`] samples in parallel, each with
    /// its own stream, added in chunk order; the chunks' deposits.
    fn meter_chunks(&mut self, mi: usize, spp: u32, pass: u64) -> Vec<Deposit> {
        let scene = self.scene;
        let integrator = self.integrator.as_ref();
        let seed = self.seed;
        let per_meter = spp as u64 * self.meter_samples;
        let chunks = per_meter.div_ceil(METER_CHUNK);
        let results: Vec<(MeterAccum, u64, Option<Deposit>)> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let n = METER_CHUNK.min(per_meter - c * METER_CHUNK);
                let stream = METER_STREAM_SALT ^ ((mi as u64) << 40) ^ c;
                let mut sampler = Sampler::new(seed, stream, pass);
                let mut acc = MeterAccum::default();
                let mut nans = 0;
                let mut scratch = Scratch::default();
                for _ in 0..n {
                    let e = integrator.meter_sample(scene, mi as u32, &mut sampler, &mut scratch);
                    acc.samples += 1;
                    if !e.is_finite() {
                        nans += 1;
                        continue;
                    }
                    for ch in 0..3 {
                        let v = e[ch] as f64;
                        acc.sum[ch] += v;
                        acc.sum_sq[ch] += v * v;
                    }
                }
                (acc, nans, integrator.deposit(&mut scratch.own))
            })
            .collect();
        let mut records = Vec::with_capacity(results.len());
        for (acc, nans, chunk_deposit) in results {
            records.extend(chunk_deposit);
            let m = &mut self.meters[mi];
            for ch in 0..3 {
                m.sum[ch] += acc.sum[ch];
                m.sum_sq[ch] += acc.sum_sq[ch];
            }
            m.samples += acc.samples;
            self.nan_count += nans;
        }
        self.paths += per_meter;
        records
    }

    /// The integrator's techniques one by one ([`Integrator::technique_images`]: BDPT's (s, t)
    /// strategies, MIS-weighted so that they sum to the BDPT image), each with at most
    /// `max_depth_shown` scattering vertices: one pass of `spp` samples per pixel, deterministic
    /// like `pass`; empty for an integrator without techniques to show.
    pub fn strategy_images(
        &self,
        spp: u32,
        max_depth_shown: u32,
    ) -> std::collections::BTreeMap<(usize, usize), Film> {
        self.integrator
            .technique_images(self.scene, self.seed, self.passes, spp, max_depth_shown)
            .unwrap_or_default()
    }

    /// Every meter's estimate.
    pub fn meter_estimates(&self) -> Vec<MeterEstimate> {
        self.scene
            .sensors
            .iter()
            .zip(&self.meters)
            .map(|(s, a)| a.estimate(&s.name))
            .collect()
    }
}
