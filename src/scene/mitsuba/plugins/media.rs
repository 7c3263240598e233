//! The media `homogeneous` and `heterogeneous` (a `gridvolume`) and the phase functions
//! `isotropic` and `hg`.

use glam::{DMat3, DMat4, DVec3};
use roxmltree::Node;

use super::{f3, linear, rgb, show, Doc, Importer, Props, Response};
use crate::scene::file::{MediumDesc, PhaseDesc, PropagationDesc};
use crate::scene::SceneError;

impl<'a, 'd> Importer<'a, 'd> {
    /// The medium a `<medium>` becomes (memoized by element).
    pub(super) fn medium(&mut self, node: Node<'a, 'a>) -> Result<String, SceneError> {
        if let Some(name) = self.media.get(&node.id()) {
            return Ok(name.clone());
        }
        let mut p = Props::new(self.doc, node)?;
        let scale = p.float("scale")?.unwrap_or(1.0);
        let phase = match p.object("phase", None)? {
            Some(ph) => phase(self.doc, ph)?,
            None => PhaseDesc::Isotropic {},
        };
        p.ignore(&["sample_emitters", "has_spectral_extinction"]);
        let plugin = p.plugin.clone();
        let (desc, how) = match plugin.as_str() {
            "homogeneous" => homogeneous(p, scale, phase)?,
            "heterogeneous" => self.heterogeneous(p, scale, phase)?,
            k => {
                return Err(p.err(format!(
                    "the medium `{k}` is not supported (homogeneous, heterogeneous are)"
                )))
            }
        };
        let name = match node.attribute("id") {
            Some(id) if !self.out.media.contains_key(id) => id.to_string(),
            _ => format!("medium@{}", self.doc.line(node)),
        };
        let key = format!("media.{name}");
        self.note(node, &key, how);
        self.out.media.insert(name.clone(), desc);
        self.media.insert(node.id(), name.clone());
        Ok(name)
    }

    /// `heterogeneous`: a `gridvolume` of sigma_t (`scale` times its values) and a constant
    /// `albedo`, as pathspace's grid medium scaling sigma_s and sigma_a per unit density.
    fn heterogeneous(
        &mut self,
        mut p: Props<'a, 'd>,
        scale: f64,
        phase: PhaseDesc,
    ) -> Result<(MediumDesc, String), SceneError> {
        let albedo = p
            .color("albedo", Response::Bounded)?
            .unwrap_or(DVec3::splat(0.75));
        let grid = p
            .object("volume", Some("sigma_t"))?
            .ok_or_else(|| p.err("`sigma_t` must be a <volume type=\"gridvolume\">"))?;
        p.finish()?;
        let (file, min, max) = self.gridvolume(grid)?;
        let (ss, sa) = (albedo * scale, (DVec3::ONE - albedo) * scale);
        Ok((
            MediumDesc::Grid {
                sigma_a: rgb(sa),
                sigma_s: rgb(ss),
                phase,
                emission: None,
                file: file.clone(),
                min: Some(f3(min)),
                max: Some(f3(max)),
                propagation: PropagationDesc::DeltaTracking,
                step: None,
            },
            format!("grid `{file}` (values at cell centres: lattice {} .. {}), sigma_s = scale albedo = {}, sigma_a = {} per unit density", show(min), show(max), show(ss), show(sa)),
        ))
    }

    /// A `gridvolume`: its file and the lattice box of pathspace's grid. Mitsuba 3 puts the
    /// values at the cell centres of the unit cube mapped by `to_world` (ignoring the file's
    /// box) and clamps beyond the outer centres; pathspace's lattice spans its box, so the box
    /// is the outer centres and the grid's faces must be zero (the clamped shell then is too).
    pub(super) fn gridvolume(
        &self,
        node: Node<'a, 'a>,
    ) -> Result<(String, DVec3, DVec3), SceneError> {
        let mut p = Props::new(self.doc, node)?;
        if p.plugin != "gridvolume" {
            return Err(p.err(format!(
                "the volume `{}` is not supported (gridvolume is)",
                p.plugin
            )));
        }
        let file = p
            .string("filename")?
            .ok_or_else(|| p.err("`filename` is missing"))?;
        if file.to_ascii_lowercase().ends_with(".vdb") {
            return Err(p.err(format!("`{file}`: Mitsuba 3's gridvolume reads `.vol` files and has no OpenVDB reader; a `.vdb` is read by a TOML scene's medium of type = \"vdb\"")));
        }
        let m = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
        if p.string("filter_type")?.is_some_and(|f| f != "trilinear") {
            return Err(p.err("only filter_type = \"trilinear\" is supported"));
        }
        if p.string("wrap_mode")?.is_some_and(|f| f != "clamp") {
            return Err(p.err("only wrap_mode = \"clamp\" is supported"));
        }
        if p.boolean("use_grid_bbox")? == Some(true) {
            return Err(p.err("use_grid_bbox = true is not supported"));
        }
        p.ignore(&["raw", "accel"]);
        p.finish()?;
        let l = linear(&m);
        let diag = DVec3::new(l.x_axis.x, l.y_axis.y, l.z_axis.z);
        if l != DMat3::from_diagonal(diag) || diag.min_element() <= 0.0 {
            return Err(self.doc.err(node, "the grid's to_world must be a positive scale and a translation (pathspace's grids are axis-aligned)"));
        }
        let path = self.base_dir.join(&file);
        let g = crate::medium::grid::read_grid_file(&path)
            .map_err(|e| self.doc.err(node, e.to_string()))?
            .grid;
        if !faces_are_zero(&g) {
            return Err(self.doc.err(node, format!("`{file}` is not zero on its faces: Mitsuba 3 holds the outer values over the last half cell, pathspace's lattice ends there; pad the grid with zeros")));
        }
        let res = DVec3::new(g.res[0] as f64, g.res[1] as f64, g.res[2] as f64);
        let lo = (DVec3::splat(0.5) / res) * diag + m.w_axis.truncate();
        let hi = (DVec3::ONE - DVec3::splat(0.5) / res) * diag + m.w_axis.truncate();
        Ok((file, lo, hi))
    }
}

/// `homogeneous`: `scale` times `sigma_t`, split by `albedo` into sigma_s and sigma_a.
fn homogeneous(
    mut p: Props,
    scale: f64,
    phase: PhaseDesc,
) -> Result<(MediumDesc, String), SceneError> {
    let st = p.color("sigma_t", Response::Bounded)?.unwrap_or(DVec3::ONE) * scale;
    let albedo = p
        .color("albedo", Response::Bounded)?
        .unwrap_or(DVec3::splat(0.75));
    p.finish()?;
    let (ss, sa) = (st * albedo, st * (DVec3::ONE - albedo));
    Ok((
        MediumDesc::Homogeneous { sigma_a: rgb(sa), sigma_s: rgb(ss), phase, emission: None },
        format!("homogeneous, sigma_s = scale sigma_t albedo = {}, sigma_a = scale sigma_t (1 - albedo) = {}", show(ss), show(sa)),
    ))
}

/// A phase function: `isotropic`, or `hg` with Mitsuba's default g = 0.8.
fn phase(doc: &Doc, node: Node) -> Result<PhaseDesc, SceneError> {
    let mut p = Props::new(doc, node)?;
    let ph = match p.plugin.as_str() {
        "isotropic" => PhaseDesc::Isotropic {},
        // Mitsuba's g > 0 scatters forwards, as pathspace's
        "hg" => PhaseDesc::Hg {
            g: p.float("g")?.unwrap_or(0.8) as f32,
        },
        k => {
            return Err(p.err(format!(
                "the phase function `{k}` is not supported (isotropic, hg are)"
            )))
        }
    };
    p.finish()?;
    Ok(ph)
}

/// Whether every value on the six faces of the lattice is zero.
fn faces_are_zero(g: &crate::medium::grid::Grid) -> bool {
    let [nx, ny, nz] = g.res;
    (0..nz).all(|z| {
        (0..ny).all(|y| {
            (0..nx).all(|x| {
                let face = x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                !face || g.values[x + nx * (y + ny * z)] == 0.0
            })
        })
    })
}
