//! Mitsuba 3 plugins, one function each, translated into pathspace's scene-file descriptions
//! with Mitsuba's conventions and defaults; anything without an exact counterpart is refused.
//! One file per part of a scene, as the build it feeds (`scene::build`): `sensor` (with film and
//! sampler), `shapes`, `bsdfs`, `media` and `emitters`; here the translation in progress, the
//! scene's top-level elements, the integrator and the values every part writes.

use glam::{DMat3, DMat4, DVec3};
use roxmltree::{Node, NodeId};
use std::collections::HashMap;
use std::path::PathBuf;

mod bsdfs;
mod emitters;
mod media;
mod sensor;
mod shapes;

use super::props::{Doc, Props, Response};
use super::FORMAT;
use crate::scene::file::{Origin, RgbValue, SceneFile};
use crate::scene::SceneError;

/// The translation in progress.
pub(super) struct Importer<'a, 'd> {
    doc: &'d Doc<'a>,
    base_dir: PathBuf,
    out: SceneFile,
    origin: Origin,
    materials: HashMap<NodeId, String>,
    media: HashMap<NodeId, String>,
    render: toml::Table,
    integrator: Option<(String, Node<'a, 'a>)>,
    sensor_seen: bool,
}

fn rgb(v: DVec3) -> RgbValue {
    if v.x == v.y && v.y == v.z {
        RgbValue::Scalar(v.x as f32)
    } else {
        RgbValue::Triple([v.x as f32, v.y as f32, v.z as f32])
    }
}

/// A vector for `info`: six significant decimals, one number when the three agree.
fn show(v: DVec3) -> String {
    let n = |x: f64| {
        let t = format!("{x:.6}");
        let t = t.trim_end_matches('0').trim_end_matches('.');
        if t == "-0" {
            "0".to_string()
        } else {
            t.to_string()
        }
    };
    if v.x == v.y && v.y == v.z {
        n(v.x)
    } else {
        format!("[{}, {}, {}]", n(v.x), n(v.y), n(v.z))
    }
}

fn f3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The linear part of an affine map.
fn linear(m: &DMat4) -> DMat3 {
    DMat3::from_mat4(*m)
}

/// Whether `l` is `s` times a rotation (s > 0), to a relative 1e-6.
fn similarity(l: &DMat3) -> Option<f64> {
    let s2 = (l.transpose() * *l).col(0).x;
    let e = l.transpose() * *l - DMat3::IDENTITY * s2;
    let ok = s2 > 0.0 && e.to_cols_array().iter().all(|x| x.abs() <= 1e-6 * s2);
    (ok && l.determinant() > 0.0).then(|| s2.sqrt())
}

impl<'a, 'd> Importer<'a, 'd> {
    pub fn new(doc: &'d Doc<'a>, base_dir: PathBuf) -> Self {
        Importer {
            doc,
            base_dir,
            out: SceneFile::default(),
            origin: Origin {
                format: FORMAT.into(),
                ..Origin::default()
            },
            materials: HashMap::new(),
            media: HashMap::new(),
            render: toml::Table::new(),
            integrator: None,
            sensor_seen: false,
        }
    }

    fn note(&mut self, node: Node, key: &str, how: String) {
        self.origin
            .lines
            .push((key.to_string(), self.doc.line(node)));
        self.origin.notes.push(format!(
            "{}: <{} type=\"{}\"> -> {key}: {how}",
            self.doc.at(node),
            node.tag_name().name(),
            node.attribute("type").unwrap_or("")
        ));
    }

    /// The scene's top-level elements, in order.
    pub fn scene(&mut self, root: Node<'a, 'a>) -> Result<(), SceneError> {
        for c in root.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "default" => {}
                // referenced by id where used; an unused one does not change the image
                "bsdf" | "medium" | "texture" | "phase" | "volume" | "rfilter" => {
                    if c.attribute("id").is_none() {
                        return Err(self.doc.err(c, "a top-level element needs an `id`"));
                    }
                }
                "integrator" => self.integrator(c)?,
                "sensor" => self.sensor(c)?,
                "shape" => self.shape(c)?,
                "emitter" => self.emitter(c)?,
                "include" => {
                    return Err(self
                        .doc
                        .err(c, "<include> is not supported: paste the file in"))
                }
                t => return Err(self.doc.err(c, format!("<{t}> is not supported"))),
            }
        }
        Ok(())
    }

    /// The render settings and the checks that need the whole scene.
    pub fn finish(mut self, root: Node) -> Result<(SceneFile, Origin), SceneError> {
        if !self.sensor_seen {
            return Err(self.doc.err(root, "the scene has no <sensor>"));
        }
        let (kind, node) = self.integrator.clone().unwrap_or(("path".into(), root));
        if (kind == "path" || kind == "direct") && !self.out.media.is_empty() {
            return Err(self.doc.err(
                node,
                format!("Mitsuba's `{kind}` integrator ignores media, but the scene has some: use `volpath`"),
            ));
        }
        if self.out.hide_emitters {
            self.hidden_emitters_exact(&kind, node)?;
        }
        self.render.insert("integrator".into(), "path".into());
        self.origin
            .lines
            .push(("render".into(), self.doc.line(node)));
        self.out.render = Some(self.render);
        Ok((self.out, self.origin))
    }

    fn integrator(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let kind = p.plugin.clone();
        if !["path", "volpath", "volpathmis", "direct"].contains(&kind.as_str()) {
            return Err(p.err(format!(
                "the integrator `{kind}` is not supported (path, volpath, volpathmis, direct are)"
            )));
        }
        let (max_depth, rr) = if kind == "direct" {
            direct_samples(&mut p)?;
            (2, 5)
        } else {
            let d = p.integer("max_depth")?.unwrap_or(-1);
            (d, p.integer("rr_depth")?.unwrap_or(5))
        };
        let hide = p.boolean("hide_emitters")? == Some(true);
        p.finish()?;
        if hide {
            self.out.hide_emitters = true;
            self.note(
                node,
                "hide_emitters",
                "paths with no scattering vertex left out (pathspace's `hide_emitters`)".into(),
            );
        }
        // Mitsuba counts path segments (1: emitters seen directly), pathspace scattering vertices
        let depth = match max_depth {
            -1 => None,
            d if d >= 1 => Some(d - 1),
            d => {
                return Err(self.doc.err(
                    node,
                    format!("max_depth = {d}: Mitsuba renders nothing below 1 (-1 is unlimited)"),
                ))
            }
        };
        if let Some(d) = depth {
            self.render
                .insert("max_depth".into(), toml::Value::Integer(d));
        }
        self.integrator = Some((kind.clone(), node));
        let how = if kind == "direct" {
            "emitters seen directly and lit once: the path tracer with max_depth 1 (Mitsuba's `path` with max_depth 2)".to_string()
        } else {
            format!(
                "max_depth {} (Mitsuba's {max_depth} counts segments); rr_depth {rr} not used (pathspace's own roulette, unbiased either way)",
                depth.map_or("unlimited".into(), |d| d.to_string())
            )
        };
        self.note(
            node,
            "render",
            format!("pathspace's volumetric path tracer, {how}"),
        );
        Ok(())
    }
}

impl Importer<'_, '_> {
    /// Mitsuba's `hide_emitters` as pathspace's (no path without a scattering vertex; area
    /// emitters transparent to the camera's rays until then), refused where they differ
    /// (Mitsuba 3.9.1, `path.cpp`, `volpath.cpp`, `volpathmis.cpp`, `direct.cpp`): `path` and
    /// `direct` skip area emitters on the camera's first ray alone, so behind a null surface
    /// one is hit again (and `direct` shows it); `volpath` and `volpathmis` skip them only on
    /// the intersections they make outside media, so inside one it is opaque again.
    fn hidden_emitters_exact(&self, kind: &str, node: Node) -> Result<(), SceneError> {
        let shapes = || self.out.shapes.iter().map(|s| s.common());
        let area = shapes().any(|c| c.emission.is_some());
        let null = shapes().any(|c| c.material.as_deref() == Some("null"));
        let why = if kind == "direct" && null {
            "hide_emitters = true under `direct` with a null surface: Mitsuba's `direct` shows emitters through it"
        } else if area && kind == "path" && null {
            "hide_emitters = true under `path` with an area emitter and a null surface: Mitsuba's `path` sees through area emitters on the camera's first ray only, not behind a null surface"
        } else if area && !self.out.media.is_empty() {
            "hide_emitters = true with an area emitter and a medium: Mitsuba's `volpath` sees through area emitters only outside media, inside one they stop the camera's ray again"
        } else {
            return Ok(());
        };
        Err(self.doc.err(node, why))
    }
}

/// The `direct` integrator's sample counts (Mitsuba 3 documentation, plugin `direct`:
/// `shading_samples`, 1 by default, or `emitter_samples` and `bsdf_samples`). Its estimate is
/// the power-heuristic combination of both strategies, whose expectation, the light arriving
/// after one scattering, is `path`'s with max_depth 2 only while each strategy has a sample:
/// without emitter samples Mitsuba misses point lights, without BSDF samples mirrors.
fn direct_samples(p: &mut Props) -> Result<(), SceneError> {
    let shading = p.integer("shading_samples")?;
    let (emitter, bsdf) = (p.integer("emitter_samples")?, p.integer("bsdf_samples")?);
    if shading.is_some() && (emitter.is_some() || bsdf.is_some()) {
        return Err(p.err(
            "shading_samples with emitter_samples or bsdf_samples: Mitsuba refuses both at once",
        ));
    }
    let shading = shading.unwrap_or(1);
    for (k, v) in [
        ("emitter_samples", emitter.unwrap_or(shading)),
        ("bsdf_samples", bsdf.unwrap_or(shading)),
    ] {
        if v < 1 {
            return Err(p.err(format!(
                "{k} = {v}: without samples of both strategies Mitsuba's `direct` misses light (point lights without emitter samples, mirrors without BSDF samples)"
            )));
        }
    }
    Ok(())
}
