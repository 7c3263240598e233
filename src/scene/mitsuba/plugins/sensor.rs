//! The `perspective` and `thinlens` sensors with their `hdrfilm` and sampler: the camera and
//! the `[render]` table's resolution, samples and seed.

use glam::{DMat4, DVec3};
use roxmltree::Node;

use super::{f3, linear, similarity, Importer, Props};
use crate::film::filter::MAX_RADIUS;
use crate::scene::file::{CameraDesc, FilterDesc};
use crate::scene::SceneError;

/// A `perspective` or `thinlens` sensor's own properties, read and checked, with its film and
/// sampler.
struct Perspective<'a> {
    /// Degrees along `axis`.
    fov: f64,
    /// The thin lens's `aperture_radius` and `focus_distance` (Mitsuba 3 documentation, plugin
    /// `thinlens`; the focus distance defaults to `far_clip`, as `ProjectiveCamera` reads it);
    /// `None` for `perspective`.
    lens: Option<(f64, f64)>,
    axis: String,
    to_world: DMat4,
    medium: Option<String>,
    film: Node<'a, 'a>,
    sampler: Option<Node<'a, 'a>>,
}

impl<'a, 'd> Importer<'a, 'd> {
    /// The scene's one sensor: the camera, and the resolution, samples and seed of `[render]`.
    pub(super) fn sensor(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        if self.sensor_seen {
            return Err(self.doc.err(node, "only one <sensor> is supported"));
        }
        self.sensor_seen = true;
        let Perspective {
            fov,
            lens,
            axis,
            to_world: m,
            medium,
            film,
            sampler,
        } = self.perspective(node)?;
        let (w, h, filter) = self.film(film)?;
        let (spp, seed) = match sampler {
            Some(s) => self.sampler(s)?,
            None => (4, 0),
        };
        let tan_y = vertical_tan(fov, &axis, w, h).ok_or_else(|| {
            self.doc
                .err(node, format!("fov_axis = \"{axis}\" is unknown"))
        })?;
        let l = linear(&m);
        if similarity(&l).is_none_or(|s| (s - 1.0).abs() > 1e-6) {
            return Err(self.doc.err(
                node,
                "the sensor's to_world must be a rotation and a translation (no scale, no mirror)",
            ));
        }
        let eye = m.w_axis.truncate();
        let forward = l * DVec3::Z;
        // Mitsuba replaces a zero aperture by its float epsilon: the pinhole's image
        let (aperture_radius, focus_distance) = match lens {
            Some((r, f)) if r > 0.0 => (r as f32, Some(f as f32)),
            _ => (0.0, None),
        };
        self.out.camera = Some(CameraDesc::Pinhole {
            eye: f3(eye),
            look_at: f3(eye + forward),
            up: f3(l * DVec3::Y),
            fov_deg: (2.0 * tan_y.atan()).to_degrees() as f32,
            resolution: [w, h],
            aperture_radius,
            focus_distance,
            filter,
        });
        self.render.insert("spp".into(), toml::Value::Integer(spp));
        self.render
            .insert("seed".into(), toml::Value::Integer(seed));
        self.origin.camera_medium = medium.clone();
        self.note(
            node,
            "camera",
            format!(
                "{}, fov {fov} deg along {axis} = {:.4} deg vertical, {w}x{h}, {} filter, {spp} spp, seed {seed}, in {}; no clipping (geometry nearer than Mitsuba's default near clip, 1 cm, or beyond a far_clip is rendered)",
                match focus_distance {
                    Some(f) => format!("thin lens of radius {aperture_radius} focused at {f}"),
                    None => "pinhole".into(),
                },
                (2.0 * tan_y.atan()).to_degrees(),
                filter_note(filter),
                medium.as_deref().unwrap_or("vacuum")
            ),
        );
        Ok(())
    }

    /// The properties of a `perspective` or `thinlens` sensor, each consumed or refused.
    fn perspective(&mut self, node: Node<'a, 'a>) -> Result<Perspective<'a>, SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "perspective" && p.plugin != "thinlens" {
            return Err(p.err(format!(
                "the sensor `{}` is not supported (perspective and thinlens are)",
                p.plugin
            )));
        }
        let (fov, axis) = field_of_view(&mut p)?;
        let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        for k in ["principal_point_offset_x", "principal_point_offset_y"] {
            if p.float(k)?.is_some_and(|x| x != 0.0) {
                return Err(p.err(format!("a nonzero {k} is not supported")));
            }
        }
        // pathspace does not clip: only Mitsuba's defaults (or wider) give the same image
        if p.float("near_clip")?.is_some_and(|x| x > 0.01) {
            return Err(p.err("a near_clip above Mitsuba's default 0.01 is not supported (pathspace does not clip)"));
        }
        // a far clip matters only inside the scene's extent, which the sensor cannot see here:
        // accepted, and `info` says it is not applied; a thin lens focuses there by default
        let far_clip = p.float("far_clip")?.unwrap_or(1e4);
        let lens = if p.plugin == "thinlens" {
            let r = p
                .float("aperture_radius")?
                .ok_or_else(|| p.err("`aperture_radius` is missing (thinlens has no default)"))?;
            let f = p.float("focus_distance")?.unwrap_or(far_clip);
            if !(r >= 0.0 && r.is_finite()) {
                return Err(p.err(format!("aperture_radius = {r} must be finite and >= 0")));
            }
            if !(f > 0.0 && f.is_finite()) {
                return Err(p.err(format!("focus_distance = {f} must be finite and > 0")));
            }
            Some((r, f))
        } else {
            // every projective camera reads it (`ProjectiveCamera`), the pinhole never uses it
            p.float("focus_distance")?;
            None
        };
        let medium = match p.object("medium", None)? {
            Some(m) => Some(self.medium(m)?),
            None => None,
        };
        let film = p
            .object("film", None)?
            .ok_or_else(|| p.err("<film> is missing"))?;
        let sampler = p.object("sampler", None)?;
        p.finish()?;
        Ok(Perspective {
            fov,
            lens,
            axis,
            to_world,
            medium,
            film,
            sampler,
        })
    }

    /// An `hdrfilm`: its size and its reconstruction filter.
    pub(super) fn film(
        &mut self,
        node: Node<'a, 'a>,
    ) -> Result<(u32, u32, FilterDesc), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "hdrfilm" {
            return Err(p.err(format!(
                "the film `{}` is not supported (hdrfilm is)",
                p.plugin
            )));
        }
        let w = p.integer("width")?.unwrap_or(768);
        let h = p.integer("height")?.unwrap_or(576);
        let filter = p.object("rfilter", None)?;
        if let Some(f) = p.string("pixel_format")? {
            if f != "rgb" && f != "rgba" {
                return Err(p.err(format!(
                    "pixel_format = \"{f}\": only rgb (or rgba) images are the same"
                )));
            }
        }
        p.ignore(&["component_format", "file_format"]);
        let border = p.boolean("sample_border")?.unwrap_or(false);
        p.finish()?;
        let filter = match filter {
            Some(f) => self.rfilter(f)?,
            // Mitsuba 3 documentation, plugin `gaussian`: the default reconstruction filter
            None => FilterDesc::Gaussian { stddev: 0.5 },
        };
        if border && filter != FilterDesc::Box {
            return Err(self.doc.err(
                node,
                "sample_border = true with a filter other than the box is not supported (camera samples stay inside the film)",
            ));
        }
        let ok = |v: i64| (1..=16384).contains(&v);
        if !(ok(w) && ok(h)) {
            return Err(self.doc.err(
                node,
                format!("{w}x{h} pixels: each side must be in 1..=16384"),
            ));
        }
        Ok((w as u32, h as u32, filter))
    }

    /// An `<rfilter>`: `box`, `tent` (radius) or `gaussian` (stddev), Mitsuba 3's defaults.
    fn rfilter(&mut self, node: Node<'a, 'a>) -> Result<FilterDesc, SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let (filter, name, v) = match p.plugin.as_str() {
            "box" => (FilterDesc::Box, "", 1.0),
            "tent" => {
                let r = p.float("radius")?.unwrap_or(1.0);
                (FilterDesc::Tent { radius: r as f32 }, "radius", r)
            }
            "gaussian" => {
                let s = p.float("stddev")?.unwrap_or(0.5);
                (FilterDesc::Gaussian { stddev: s as f32 }, "stddev", s)
            }
            other => {
                return Err(p.err(format!(
                "the reconstruction filter `{other}` is not supported (box, tent and gaussian are)"
            )))
            }
        };
        let radius = if name == "stddev" { 4.0 * v } else { v };
        if !(v > 0.0 && radius <= MAX_RADIUS) {
            return Err(p.err(format!(
                "{name} = {v} must be positive, with a filter radius of at most {MAX_RADIUS} pixels"
            )));
        }
        p.finish()?;
        Ok(filter)
    }

    pub(super) fn sampler(&mut self, node: Node<'a, 'a>) -> Result<(i64, i64), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let spp = p.integer("sample_count")?.unwrap_or(4);
        let seed = p.integer("seed")?.unwrap_or(0);
        // the pattern changes the noise, not the expectation
        p.ignore(&["jitter", "scramble_seed", "dimension"]);
        p.finish()?;
        if !(1..=1 << 30).contains(&spp) || seed < 0 {
            return Err(self
                .doc
                .err(node, "sample_count must be positive and seed non-negative"));
        }
        Ok((spp, seed))
    }
}

/// The field of view in degrees and its axis: `fov` along `fov_axis` (x by default), or a 35 mm
/// camera's diagonal at `focal_length` ("50mm" by default, the unit optional), as Mitsuba 3's
/// `parse_fov` reads them (a focal length ignores `fov_axis`, which is then refused as unused).
fn field_of_view(p: &mut Props) -> Result<(f64, String), SceneError> {
    let fov = p.float("fov")?;
    let focal = p.string("focal_length")?;
    match (fov, focal) {
        (Some(_), Some(_)) => Err(p.err("both `fov` and `focal_length`: Mitsuba takes one")),
        (Some(fov), None) => Ok((fov, p.string("fov_axis")?.unwrap_or_else(|| "x".into()))),
        (None, focal) => {
            let text = focal.unwrap_or_else(|| "50mm".into());
            let f: f64 = text
                .strip_suffix("mm")
                .unwrap_or(&text)
                .trim()
                .parse()
                .ok()
                .filter(|f: &f64| *f > 0.0 && f.is_finite())
                .ok_or_else(|| {
                    p.err(format!(
                        "focal_length = \"{text}\" must be a positive number of millimetres"
                    ))
                })?;
            // the diagonal of the 36 x 24 mm frame
            let diagonal = (36.0f64 * 36.0 + 24.0 * 24.0).sqrt();
            let fov = 2.0 * (diagonal / (2.0 * f)).atan().to_degrees();
            Ok((fov, "diagonal".into()))
        }
    }
}

/// The tangent of half the vertical field of view of `fov` degrees along Mitsuba's `fov_axis`
/// on a film of `w` x `h` pixels; `None` for an axis Mitsuba does not know.
fn vertical_tan(fov: f64, axis: &str, w: u32, h: u32) -> Option<f64> {
    let tan = (0.5 * fov.to_radians()).tan();
    let (w64, h64) = (w as f64, h as f64);
    Some(match axis {
        "x" => tan * h64 / w64,
        "y" => tan,
        "diagonal" => tan * h64 / (w64 * w64 + h64 * h64).sqrt(),
        "smaller" if w <= h => tan * h64 / w64,
        "smaller" => tan,
        "larger" if w >= h => tan * h64 / w64,
        "larger" => tan,
        _ => return None,
    })
}

/// How `info` names a filter.
fn filter_note(f: FilterDesc) -> String {
    match f {
        FilterDesc::Box => "box".into(),
        FilterDesc::Tent { radius } => format!("tent (radius {radius})"),
        FilterDesc::Gaussian { stddev } => format!("gaussian (stddev {stddev})"),
    }
}
