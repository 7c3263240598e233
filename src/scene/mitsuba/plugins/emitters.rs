//! The emitters: `area` on a shape, and `point`, `spot`, `directional`, `constant` and
//! `envmap` on their own.

use glam::{DMat4, DVec3};
use roxmltree::Node;

use super::{f3, linear, rgb, show, Importer, Props, Response};
use crate::scene::file::{EmissionValue, LightDesc, ReflectanceValue};
use crate::scene::SceneError;

impl<'a, 'd> Importer<'a, 'd> {
    /// An `area` emitter's radiance: a colour (1 by default), or a `bitmap` or `checkerboard`
    /// texture over the shape's (u, v), read as Mitsuba 3's RGB variants read it (Mitsuba 3
    /// documentation, plugin `area`: its `radiance` is a texture, evaluated at the point's
    /// (u, v); a bitmap's texels unclamped, a checkerboard's colours as for a reflectance).
    pub(super) fn area(&mut self, node: Node<'a, 'a>) -> Result<EmissionValue, SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "area" {
            return Err(p.err(format!(
                "the emitter `{}` on a shape is not supported (area is)",
                p.plugin
            )));
        }
        if let Some(t) = p.texture("radiance") {
            self.checker_rgb_in_range(t)?;
            let t = super::bsdfs::texture(self.doc, t)?;
            p.finish()?;
            return Ok(ReflectanceValue::Texture(t));
        }
        let r = p
            .color("radiance", Response::Emissive)?
            .unwrap_or(DVec3::ONE);
        p.finish()?;
        Ok(rgb(r).into())
    }

    /// Mitsuba 3 reads a checkerboard's `<rgb>` colours as reflectances even in an emitter
    /// (its parser's `srgb` texture, bounded: "must be in the range [0, 1]"), so a scene with
    /// one above 1 does not load there; refused here alike (a `<float>` is unbounded in both).
    fn checker_rgb_in_range(&self, t: Node<'a, 'a>) -> Result<(), SceneError> {
        if t.attribute("type") != Some("checkerboard") {
            return Ok(());
        }
        for c in t.children().filter(|c| c.tag_name().name() == "rgb") {
            let values = self.doc.numbers(c, &self.doc.need(c, "value")?)?;
            if values.iter().any(|&x| x > 1.0) {
                return Err(self.doc.err(
                    c,
                    "an <rgb> above 1 in a checkerboard: Mitsuba 3 reads a checkerboard's <rgb> colours as reflectances in [0, 1], even as an emitter's radiance (a <float> is unbounded)",
                ));
            }
        }
        Ok(())
    }

    /// A top-level emitter.
    pub(super) fn emitter(&mut self, node: Node<'a, 'a>) -> Result<(), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        let m = p.transform("to_world")?;
        let (light, how) = match p.plugin.as_str() {
            "point" => point(&mut p, m)?,
            "spot" => spot(&mut p, m.unwrap_or(DMat4::IDENTITY))?,
            "directional" => directional(&mut p, m)?,
            "constant" if m.is_none() => {
                let r = p
                    .color("radiance", Response::Emissive)?
                    .unwrap_or(DVec3::ONE);
                let (zenith, horizon, nadir) = (None, None, None);
                let radiance = Some(rgb(r));
                let env = LightDesc::Environment {
                    radiance,
                    zenith,
                    horizon,
                    nadir,
                    map: None,
                    scale: None,
                    to_world: None,
                    sampling: None,
                };
                (env, format!("constant environment, radiance {}", show(r)))
            }
            "constant" => return Err(p.err("a constant emitter takes no to_world")),
            "envmap" => envmap(&mut p, m)?,
            "area" => return Err(p.err("an `area` emitter belongs inside a <shape>")),
            k => {
                return Err(p.err(format!(
                "the emitter `{k}` is not supported (area, point, spot, directional, constant are)"
            )))
            }
        };
        p.finish()?;
        let i = self.out.lights.len();
        self.out.lights.push(light);
        self.note(node, &format!("lights[{i}]"), how);
        Ok(())
    }
}

/// A light and its note.
type Lighting = Result<(LightDesc, String), SceneError>;

/// `envmap`: a lat-long EXR (`filename`, relative to the XML file) times `scale`, turned by
/// the rotation `to_world` (the mapping is Mitsuba's; pathspace looks texels up without
/// Mitsuba's bilinear interpolation).
fn envmap(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let map = p
        .string("filename")?
        .ok_or_else(|| p.err("`filename` is missing"))?;
    let scale = p.float("scale")?.map(|x| x as f32);
    let to_world = match m {
        None => None,
        Some(m) if m.w_axis.truncate() != DVec3::ZERO => return Err(p.err(
            "an envmap's to_world must be a rotation (a translation has no meaning at infinity)",
        )),
        Some(m) => Some([0, 1, 2].map(|i| m.row(i).truncate().to_array().map(|x| x as f32))),
    };
    let how = format!(
        "environment map `{map}`, scale {}, looked up bilinearly and sampled by luminance as Mitsuba",
        scale.unwrap_or(1.0)
    );
    let light = LightDesc::Environment {
        radiance: None,
        zenith: None,
        horizon: None,
        nadir: None,
        map: Some(map),
        scale,
        to_world,
        sampling: None,
    };
    Ok((light, how))
}

/// `point`: at `position` or the origin of `to_world`, `intensity` in W/sr.
fn point(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let pos = match (p.point("position")?, m) {
        (Some(x), None) => x,
        (None, Some(m)) => m.w_axis.truncate(),
        (None, None) => DVec3::ZERO,
        (Some(_), Some(_)) => return Err(p.err("give `position` or `to_world`, not both")),
    };
    let i = p
        .color("intensity", Response::Emissive)?
        .unwrap_or(DVec3::ONE);
    let how = format!("point light at {}, intensity {} W/sr", show(pos), show(i));
    let (position, intensity) = (f3(pos), rgb(i));
    Ok((
        LightDesc::Point {
            position,
            intensity,
        },
        how,
    ))
}

/// `spot`: along local +z of `to_world`; only the hard cone (`beam_width` = `cutoff_angle`)
/// is the same light in both renderers.
fn spot(p: &mut Props, m: DMat4) -> Lighting {
    let i = p
        .color("intensity", Response::Emissive)?
        .unwrap_or(DVec3::ONE);
    let cutoff = p.float("cutoff_angle")?.unwrap_or(20.0);
    let beam = p.float("beam_width")?.unwrap_or(0.75 * cutoff);
    if beam != cutoff {
        return Err(p.err(format!("beam_width {beam} differs from cutoff_angle {cutoff}: Mitsuba's falloff is linear in the angle, pathspace's a smoothstep in the cosine; set beam_width = cutoff_angle for a hard cone")));
    }
    let (pos, dir) = (m.w_axis.truncate(), linear(&m) * DVec3::Z);
    let how = format!(
        "spot light at {} along {}, intensity {} W/sr, hard cone {cutoff} deg",
        show(pos),
        show(dir),
        show(i)
    );
    let (position, direction, intensity) = (f3(pos), f3(dir), rgb(i));
    let (cone_deg, falloff_deg) = (cutoff as f32, 0.0);
    let light = LightDesc::Spot {
        position,
        direction,
        intensity,
        cone_deg,
        falloff_deg,
    };
    Ok((light, how))
}

/// `directional`: light travelling along `direction` (or local +z of `to_world`).
fn directional(p: &mut Props, m: Option<DMat4>) -> Lighting {
    let dir = match (p.point("direction")?, m) {
        (Some(d), None) => d,
        (None, Some(m)) => linear(&m) * DVec3::Z,
        (None, None) => DVec3::Z,
        (Some(_), Some(_)) => return Err(p.err("give `direction` or `to_world`, not both")),
    };
    let e = p
        .color("irradiance", Response::Emissive)?
        .unwrap_or(DVec3::ONE);
    let how = format!(
        "directional light along {}, irradiance {}",
        show(dir),
        show(e)
    );
    let (direction, irradiance) = (f3(dir), rgb(e));
    Ok((
        LightDesc::Directional {
            direction,
            irradiance,
        },
        how,
    ))
}
