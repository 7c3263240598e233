//! Layers written beside the image (arbitrary output variables, AOVs): the per-pixel variance
//! of the mean and the relative variance the render measured, and first-hit features (albedo,
//! shading normal, depth, position) from a pass of their own, for denoisers and for judging a
//! render without a reference. Channel names are pbrt-v4's G-buffer film's where it has one
//! (`Albedo.R`, `Ns.X`, `P.X`, `Variance.R`, `RelativeVariance.R`), OpenEXR's `Z` for depth.
//! `merge` combines them by [`merge_channels`].
//! Book: "Measuring a renderer" (the layers and their definitions).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bsdf::Bsdf;
use crate::geometry::Ray;
use crate::image_io::{Channel, Image};
use crate::integrator::IntegratorKind;
use crate::math::sampler::mix64;
use crate::math::Sampler;
use crate::measure::metrics::RELMSE_EPSILON;
use crate::scene::{Event, Scene};
use crate::spectrum::Rgb;

/// One layer `--aovs` can ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Aov {
    /// Var[mean] per pixel and channel: the sample variance of the pixel's samples over n.
    Variance,
    /// Var[mean] / (mean^2 + epsilon), the per-pixel term of the estimated relMSE.
    RelativeVariance,
    /// The first event's reflectance (surface) or single-scattering albedo (medium).
    Albedo,
    /// The first surface's normal, facing the camera; the zero vector in a medium.
    Normal,
    /// The first event's distance from the eye along the camera ray.
    Depth,
    /// The first event's point in world space.
    Position,
    /// Samples (or mutations) per pixel.
    Spp,
}

impl Aov {
    pub const ALL: [Aov; 7] = [
        Aov::Variance,
        Aov::RelativeVariance,
        Aov::Albedo,
        Aov::Normal,
        Aov::Depth,
        Aov::Position,
        Aov::Spp,
    ];

    /// Its name in `--aovs`.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Variance => "variance",
            Aov::RelativeVariance => "relative-variance",
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Position => "position",
            Aov::Spp => "spp",
        }
    }

    /// The EXR channels it writes.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Aov::Variance => &["Variance.R", "Variance.G", "Variance.B"],
            Aov::RelativeVariance => &[
                "RelativeVariance.R",
                "RelativeVariance.G",
                "RelativeVariance.B",
            ],
            Aov::Albedo => &["Albedo.R", "Albedo.G", "Albedo.B"],
            Aov::Normal => &["Ns.X", "Ns.Y", "Ns.Z"],
            Aov::Depth => &["Z"],
            Aov::Position => &["P.X", "P.Y", "P.Z"],
            Aov::Spp => &["spp"],
        }
    }

    /// Whether it comes from the render's per-pixel variance (not from the feature pass).
    pub fn needs_variance(self) -> bool {
        matches!(self, Aov::Variance | Aov::RelativeVariance)
    }

    /// Whether it comes from the feature pass.
    pub fn is_feature(self) -> bool {
        matches!(self, Aov::Albedo | Aov::Normal | Aov::Depth | Aov::Position)
    }

    /// The layer a channel belongs to.
    pub fn of_channel(name: &str) -> Option<Aov> {
        Aov::ALL.into_iter().find(|a| a.channels().contains(&name))
    }

    /// Parses `--aovs`: names separated by commas (`all` for every layer), each once, in the
    /// order of [`Aov::ALL`].
    pub fn parse_list(text: &str) -> Result<Vec<Aov>, String> {
        let mut out = Vec::new();
        for word in text.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            if word == "all" {
                out.extend(Aov::ALL);
                continue;
            }
            let aov = Aov::ALL
                .into_iter()
                .find(|a| a.name() == word)
                .ok_or_else(|| {
                    let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
                    format!("unknown layer `{word}` (layers: {}, all)", names.join(", "))
                })?;
            out.push(aov);
        }
        if out.is_empty() {
            return Err("no layer named (layers are separated by commas)".into());
        }
        out.sort();
        out.dedup();
        Ok(out)
    }
}

/// The layers of `--aovs`, as clap reads them (one value: names separated by commas).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AovList(pub Vec<Aov>);

impl std::str::FromStr for AovList {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        Aov::parse_list(text).map(AovList)
    }
}

/// Refuses the variance layers for an integrator whose film does not hold each pixel's
/// samples: light tracing, BDPT's light-tracing strategies and MLT deposit their contributions
/// as splats in other pixels, whose per-pixel variance is not recorded.
pub fn refuse_variance(aovs: &[Aov], kind: IntegratorKind) -> Result<(), String> {
    let asked = aovs.iter().find(|a| a.needs_variance());
    match asked {
        Some(a) if !kind.facts().pixel_variance() => Err(format!(
            "--aovs {} needs --integrator {}: `{}` splats contributions into other \
             pixels, whose per-pixel variance the film does not record (merge independent \
             renders and use their spread instead)",
            a.name(),
            IntegratorKind::names_where(|f| f.pixel_variance()),
            kind.name()
        )),
        _ => Ok(()),
    }
}

/// Camera samples per pixel of the feature pass (4 x 4 strata).
pub const FEATURE_SAMPLES: u32 = 16;

/// Set into the seed of the feature pass's streams, so that they are none of the render's.
const FEATURE_STREAMS: u64 = 0x4145_4f56_4645_4154;

/// What one camera ray meets first: zero everywhere for a ray that leaves the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstEvent {
    pub albedo: Rgb,
    pub normal: Vec3,
    pub depth: f32,
    pub position: Vec3,
}

/// The per-pixel means of [`FirstEvent`] over the feature pass's samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    pub width: u32,
    pub height: u32,
    pub albedo: Vec<Rgb>,
    pub normal: Vec<Vec3>,
    pub depth: Vec<f32>,
    pub position: Vec<Vec3>,
}

/// The first event along `ray` from the camera's medium, propagated by Table 1 as the path
/// tracer does (through null boundaries, a collision sampled by free flight in each medium).
pub fn first_event(scene: &Scene, ray: Ray, sampler: &mut Sampler) -> FirstEvent {
    let prop = scene.propagate_from(ray, 0.0, scene.camera_medium, true, sampler);
    match prop.event {
        Event::Escape => FirstEvent::default(),
        Event::Medium { p, medium, .. } => FirstEvent {
            albedo: scene.media[medium as usize].albedo(),
            normal: Vec3::ZERO,
            depth: (p - ray.o).length(),
            position: p,
        },
        Event::Surface { hit, .. } => {
            let wo = -ray.d;
            let albedo = scene
                .bsdf_at(hit.prim, hit.p)
                .map_or(Rgb::ZERO, |b| surface_albedo(&b, wo, hit.ng));
            FirstEvent {
                albedo,
                normal: if wo.dot(hit.ng) < 0.0 {
                    -hit.ng
                } else {
                    hit.ng
                },
                depth: (hit.p - ray.o).length(),
                position: hit.p,
            }
        }
    }
}

/// A surface's albedo seen from `wo`, in [0, 1] as denoisers expect: the diffuse reflectance,
/// a mirror's reflectance, a conductor's Fresnel reflectance, 1 for dielectrics (the colour
/// of what is seen through them is not theirs), plastics' coat and base mixed by the coat's
/// Fresnel reflectance; 0 behind a one-sided surface.
pub fn surface_albedo(bsdf: &Bsdf, wo: Vec3, n: Vec3) -> Rgb {
    if bsdf.black_behind(wo, n) {
        return Rgb::ZERO;
    }
    let a = bsdf.albedo(wo.dot(n).abs());
    a.clamp(Rgb::ZERO, Rgb::ONE)
}

/// The feature pass: per pixel, the mean [`FirstEvent`] of [`FEATURE_SAMPLES`] camera rays
/// through a jittered 4 x 4 grid of the pixel, from streams of `seed` and the pixel (the same
/// features at any thread count); `None` without a camera.
pub fn features(scene: &Scene, seed: u64) -> Option<Features> {
    let cam = scene.camera.as_ref()?;
    let (w, h) = (cam.width, cam.height);
    let side = (FEATURE_SAMPLES as f32).sqrt() as u32;
    let pixels: Vec<FirstEvent> = (0..w * h)
        .into_par_iter()
        .map(|index| {
            let (x, y) = ((index % w) as f32, (index / w) as f32);
            let mut sampler = Sampler::new(mix64(seed ^ FEATURE_STREAMS), index as u64, 0);
            let mut sum = FirstEvent::default();
            for s in 0..side * side {
                let u = sampler.next_2d();
                let stratum = Vec2::new((s % side) as f32, (s / side) as f32);
                let raster = Vec2::new(x, y) + (stratum + u) / side as f32;
                let e = first_event(scene, cam.sample_ray(raster, &mut sampler), &mut sampler);
                sum.albedo += e.albedo;
                sum.normal += e.normal;
                sum.depth += e.depth;
                sum.position += e.position;
            }
            let inv = 1.0 / (side * side) as f32;
            FirstEvent {
                albedo: sum.albedo * inv,
                normal: sum.normal * inv,
                depth: sum.depth * inv,
                position: sum.position * inv,
            }
        })
        .collect();
    Some(Features {
        width: w,
        height: h,
        albedo: pixels.iter().map(|e| e.albedo).collect(),
        normal: pixels.iter().map(|e| e.normal).collect(),
        depth: pixels.iter().map(|e| e.depth).collect(),
        position: pixels.iter().map(|e| e.position).collect(),
    })
}

/// The channels of vectors `v` named `names` (3 names).
fn vector_channels(names: &[&str], v: &[Vec3]) -> Vec<Channel> {
    names
        .iter()
        .enumerate()
        .map(|(c, name)| Channel {
            name: name.to_string(),
            values: v.iter().map(|p| p[c]).collect(),
        })
        .collect()
}

/// RelativeVariance: Var[mean] / (mean^2 + epsilon), epsilon the relMSE's
/// ([`RELMSE_EPSILON`]), so that its mean over pixels and channels is the estimated relMSE.
pub fn relative_variance(image: &Image, variance: &Image) -> Vec<Vec3> {
    image
        .pixels
        .iter()
        .zip(&variance.pixels)
        .map(|(m, v)| {
            let r = |c: usize| (v[c] as f64 / ((m[c] as f64).powi(2) + RELMSE_EPSILON)) as f32;
            Vec3::new(r(0), r(1), r(2))
        })
        .collect()
}

/// What the layers of a render are made of.
pub struct Sources<'a> {
    pub image: &'a Image,
    /// The per-pixel variance of the mean, where the integrator measures it.
    pub variance: Option<&'a Image>,
    pub spp: u64,
    pub features: Option<&'a Features>,
}

/// The channels of layers `aovs`; an error names a layer whose source is missing.
pub fn channels(aovs: &[Aov], s: &Sources) -> Result<Vec<Channel>, String> {
    let n = s.image.pixels.len();
    let missing = |a: Aov| format!("the layer `{}` is not available for this render", a.name());
    let mut out = Vec::new();
    for &a in aovs {
        let variance = || s.variance.ok_or_else(|| missing(a));
        let f = || s.features.ok_or_else(|| missing(a));
        match a {
            Aov::Variance => out.extend(vector_channels(a.channels(), &variance()?.pixels)),
            Aov::RelativeVariance => out.extend(vector_channels(
                a.channels(),
                &relative_variance(s.image, variance()?),
            )),
            Aov::Albedo => out.extend(vector_channels(a.channels(), &f()?.albedo)),
            Aov::Normal => out.extend(vector_channels(a.channels(), &f()?.normal)),
            Aov::Position => out.extend(vector_channels(a.channels(), &f()?.position)),
            Aov::Depth => out.push(Channel {
                name: "Z".into(),
                values: f()?.depth.clone(),
            }),
            Aov::Spp => out.push(Channel {
                name: "spp".into(),
                values: vec![s.spp as f32; n],
            }),
        }
    }
    Ok(out)
}

/// One input of [`merge_channels`]: its samples per pixel and its channels.
pub struct MergeInput<'a> {
    pub spp: u64,
    pub channels: &'a [Channel],
}

/// sum_k w_k^power x_k over the inputs' channel `name` (n values each), w_k = spp_k / sum spp;
/// `None` when an input lacks it.
fn weighted_sum(inputs: &[MergeInput], name: &str, power: i32, n: usize) -> Option<Vec<f64>> {
    let total: u64 = inputs.iter().map(|i| i.spp).sum();
    let mut acc = vec![0.0f64; n];
    for i in inputs {
        let ch = i.channels.iter().find(|c| c.name == name)?;
        if ch.values.len() != n {
            return None;
        }
        let w = (i.spp as f64 / total.max(1) as f64).powi(power);
        for (a, v) in acc.iter_mut().zip(&ch.values) {
            *a += w * *v as f64;
        }
    }
    Some(acc)
}

/// The merged channel `name` (see [`merge_channels`]), `None` when it cannot be combined.
fn merged_channel(inputs: &[MergeInput], name: &str, image: &Image) -> Option<Vec<f32>> {
    let n = image.pixels.len();
    let f32s = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    match Aov::of_channel(name) {
        Some(Aov::Spp) => {
            weighted_sum(inputs, name, 1, n)?;
            let total: u64 = inputs.iter().map(|i| i.spp).sum();
            Some(vec![total as f32; n])
        }
        Some(Aov::Variance) => weighted_sum(inputs, name, 2, n).map(f32s),
        Some(Aov::RelativeVariance) => {
            weighted_sum(inputs, name, 1, n)?;
            let rgb = name.strip_prefix("RelativeVariance.")?;
            let c = ["R", "G", "B"].iter().position(|s| *s == rgb)?;
            // recomputed from the merged variance, which every input must hold
            let var = weighted_sum(inputs, &format!("Variance.{rgb}"), 2, n)?;
            let rel = var.iter().zip(&image.pixels);
            Some(
                rel.map(|(v, m)| (v / ((m[c] as f64).powi(2) + RELMSE_EPSILON)) as f32)
                    .collect(),
            )
        }
        _ => weighted_sum(inputs, name, 1, n).map(f32s),
    }
}

/// The layers of the sample-count-weighted mean `image` of independent renders, with
/// weights w_k = spp_k / sum spp: `Variance` is sum w_k^2 Var_k (the variance of a weighted
/// sum of independent means), `RelativeVariance` is recomputed from it and `image`, `spp` is
/// the sum, and every other channel (the features) is the weighted mean. A channel that not
/// every input holds is left out and named in the second list.
pub fn merge_channels(inputs: &[MergeInput], image: &Image) -> (Vec<Channel>, Vec<String>) {
    let mut names: Vec<&str> = inputs
        .iter()
        .flat_map(|i| i.channels.iter().map(|c| c.name.as_str()))
        .collect();
    names.sort();
    names.dedup();
    let (mut kept, mut left_out) = (Vec::new(), Vec::new());
    for name in names {
        match merged_channel(inputs, name, image) {
            Some(values) => kept.push(Channel {
                name: name.to_string(),
                values,
            }),
            None => left_out.push(name.to_string()),
        }
    }
    (kept, left_out)
}
