//! How next-event estimation draws the point of a quad or triangle light (`LightPointDraw` in
//! `src/scene/light.rs`): by solid angle from reference points near the quad, by area elsewhere
//! and whenever asked for area. The solid angle is checked against the closed form of a
//! rectangle seen from a point (the four corner rectangles' solid angles added and
//! subtracted), the directions' uniformity by the solid angles of the quad's cells, and the
//! density `sample_li` returns against `pdf_li`'s, which the path tracer's MIS weights take.
//! Book: "Sampling toward lights", section "The light point: by solid angle near a quad or triangle".

use crate::common;

use common::stats::Family;
use glam::{DVec3, Vec2, Vec3};
use pathspace::math::Sampler;
use pathspace::scene::light::LightPointDraw::{self, Area, SolidAngleNear};
use pathspace::scene::light::{LightSample, NEAR_AREA_FACTOR};
use pathspace::scene::{Light, Scene, SceneSource};

/// The quad light: x in [-0.5, 0.5], z in [-0.3, 0.3] at height 1, facing down (u x v = -y).
const X: (f64, f64) = (-0.5, 0.5);
const Z: (f64, f64) = (-0.3, 0.3);
const HEIGHT: f64 = 1.0;
const AREA: f64 = 0.6;

/// The camera of every scene here (the tests sample lights, not images).
pub(super) const CAMERA: &str = r#"[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [4, 4]
"#;

/// The quad light's shape.
pub(super) const LAMP: &str = r#"
[[shapes]]
type = "quad"
origin = [-0.5, 1.0, -0.3]
u = [1.0, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
emission = [10.0, 10.0, 10.0]
"#;

/// The quad light alone, with `more` shapes.
pub(super) fn lamp_with(more: &str) -> Scene {
    let text = format!("{CAMERA}{LAMP}{more}");
    Scene::load(&SceneSource::embedded("lamp.toml", &text)).unwrap_or_else(|e| panic!("{e}"))
}

/// The quad light alone.
fn lamp() -> Scene {
    lamp_with("")
}

/// The solid angle of the part [x0, x1] x [z0, z1] of the light's plane seen from `p` below it:
/// with the foot of the perpendicular at the origin and the height h, the rectangle
/// [0, a] x [0, b] subtends atan(a b / (h sqrt(a^2 + b^2 + h^2))), and a rectangle anywhere is
/// four of those, added and subtracted.
fn solid_angle(p: DVec3, (x0, x1): (f64, f64), (z0, z1): (f64, f64)) -> f64 {
    let h = HEIGHT - p.y;
    let corner = |a: f64, b: f64| (a * b / (h * (a * a + b * b + h * h).sqrt())).atan();
    let (a0, a1, b0, b1) = (x0 - p.x, x1 - p.x, z0 - p.z, z1 - p.z);
    corner(a1, b1) - corner(a0, b1) - corner(a1, b0) + corner(a0, b0)
}

/// A reference point below the light whose squared distance to its centre is `r2_over_area`
/// times its area, in the direction (`sx`, -1, `sz`) from the centre.
fn point_at(r2_over_area: f64, sx: f64, sz: f64) -> DVec3 {
    let dir = DVec3::new(sx, -1.0, sz).normalize();
    DVec3::new(0.0, HEIGHT, 0.0) + dir * (r2_over_area * AREA).sqrt()
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Draws 20 000 samples of the scene's first light from `p` by `draw`, hands each to `check`,
/// and adds to `fam` the comparison of the mean of 1 / pdf, an estimate of the light's solid
/// angle by either draw, with the closed form of the rectangle.
fn mean_inverse_pdf_is_the_solid_angle(
    fam: &mut Family,
    scene: &Scene,
    (p, draw): (DVec3, LightPointDraw),
    s: &mut Sampler,
    check: impl Fn(&LightSample),
) {
    let (mut sum, mut sum2, n) = (0.0, 0.0, 20_000u64);
    for _ in 0..n {
        let u = (s.next_2d(), s.next_f32());
        let ls = scene.lights[0]
            .sample_li(&scene.prims, p.as_vec3(), u, draw)
            .unwrap();
        check(&ls);
        let inv = 1.0 / ls.pdf as f64;
        (sum, sum2) = (sum + inv, sum2 + inv * inv);
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean) * n as f64 / (n - 1) as f64;
    let what = format!("{draw:?} from {p}");
    fam.samples_are(&what, mean, var, n, solid_angle(p, X, Z));
}

const NEAR_POINTS: [(f64, f64, f64); 5] = [
    (0.9, 0.0, 0.0),
    (0.5, 0.3, -0.2),
    (0.2, -0.6, 0.4),
    (0.05, 0.1, 0.1),
    (0.01, 1.5, -0.8),
];

/// From near the quad every sample has the density 1 / Omega (so L / pdf is the light's
/// radiance times its solid angle, the same for every sample: no variance is left), `pdf_li`
/// gives that density for the point drawn, and the point lies on the quad along the direction.
#[test]
fn near_points_draw_by_solid_angle_with_the_closed_form_density() {
    let scene = lamp();
    let light = &scene.lights[0];
    let Light::Area { prims, .. } = light else {
        panic!("the lamp is an area light")
    };
    let mut s = Sampler::new(7, 0, 0);
    for &(r2, sx, sz) in &NEAR_POINTS {
        assert!(r2 < NEAR_AREA_FACTOR as f64);
        let p = point_at(r2, sx, sz);
        let omega = solid_angle(p, X, Z);
        for _ in 0..400 {
            let u = (s.next_2d(), s.next_f32());
            let ls = light
                .sample_li(&scene.prims, p.as_vec3(), u, SolidAngleNear)
                .expect("a point in front of the lamp gets a sample");
            let err = relative(1.0 / ls.pdf as f64, omega);
            assert!(
                err < 2e-4,
                "at {p}: 1/pdf {} against Omega {omega}",
                1.0 / ls.pdf
            );
            let back = light.pdf_li(
                &scene.prims,
                p.as_vec3(),
                (ls.p, ls.n, prims[0]),
                SolidAngleNear,
            );
            assert!(
                relative(back as f64, ls.pdf as f64) < 1e-5,
                "pdf_li {back} against {}",
                ls.pdf
            );
            let q = ls.p.as_dvec3();
            assert!(
                (q.y - HEIGHT).abs() < 1e-5 && q.x.abs() <= 0.5 + 1e-5 && q.z.abs() <= 0.3 + 1e-5
            );
            let along = (q - p).normalize();
            assert!(
                along.dot(ls.wi.as_dvec3()) > 1.0 - 1e-6,
                "the direction points at the point"
            );
            assert!(relative((q - p).length(), ls.dist as f64) < 1e-5);
        }
    }
}

/// The directions are uniform by solid angle: over a 4 x 3 grid of the quad's cells, the
/// points drawn fall in proportion to each cell's own solid angle (chi-square per reference
/// point, one family).
#[test]
fn near_points_are_uniform_by_solid_angle_over_the_quad() {
    let scene = lamp();
    let light = &scene.lights[0];
    let mut fam = Family::new("solid-angle draw: cells of the quad");
    let mut s = Sampler::new(11, 0, 0);
    let (nx, nz, n) = (4, 3, 24_000);
    for &(r2, sx, sz) in &NEAR_POINTS {
        let p = point_at(r2, sx, sz);
        let omega = solid_angle(p, X, Z);
        let cell = |i: usize, lo: f64, hi: f64, k: usize| {
            let w = (hi - lo) / k as f64;
            (lo + w * i as f64, lo + w * (i + 1) as f64)
        };
        let mut expected = Vec::new();
        for i in 0..nx {
            for j in 0..nz {
                let part = solid_angle(p, cell(i, X.0, X.1, nx), cell(j, Z.0, Z.1, nz));
                expected.push(n as f64 * part / omega);
            }
        }
        let mut observed = vec![0u64; nx * nz];
        for _ in 0..n {
            let u = (s.next_2d(), s.next_f32());
            let ls = light
                .sample_li(&scene.prims, p.as_vec3(), u, SolidAngleNear)
                .unwrap();
            let i = (((ls.p.x as f64 - X.0) / (X.1 - X.0) * nx as f64) as usize).min(nx - 1);
            let j = (((ls.p.z as f64 - Z.0) / (Z.1 - Z.0) * nz as f64) as usize).min(nz - 1);
            observed[i * nz + j] += 1;
        }
        fam.chi_square(&format!("from {p}"), &observed, &expected);
    }
    fam.finish();
}

/// Beyond the near region, and wherever the draw is by area, a point is uniform on the quad:
/// density d^2 / (A cos) by solid angle, which `pdf_li` repeats; and the area draw's
/// estimate of the solid angle (its 1 / pdf) has the closed form's mean from near points too,
/// the unbiased but noisy estimate the solid-angle draw replaces.
#[test]
fn far_points_and_the_area_draw_keep_the_area_density() {
    let scene = lamp();
    let light = &scene.lights[0];
    let Light::Area { prims, .. } = light else {
        panic!("the lamp is an area light")
    };
    let mut fam = Family::new("area draw: the mean of 1 / pdf is the solid angle");
    let mut s = Sampler::new(5, 0, 0);
    let far = [(1.2, 0.0, 0.0), (3.0, 0.4, 0.2), (20.0, -1.0, 2.0)];
    let cases = far
        .iter()
        .map(|&f| (f, SolidAngleNear))
        .chain(NEAR_POINTS.iter().map(|&f| (f, Area)));
    for ((r2, sx, sz), draw) in cases {
        let p = point_at(r2, sx, sz);
        let check = |ls: &LightSample| {
            let d = (ls.p.as_dvec3() - p).length();
            let cos = (HEIGHT - p.y) / d;
            let area_density = d * d / (AREA * cos);
            assert!(
                relative(ls.pdf as f64, area_density) < 1e-4,
                "{draw:?} at {p}"
            );
            let back = light.pdf_li(&scene.prims, p.as_vec3(), (ls.p, ls.n, prims[0]), draw);
            assert!(relative(back as f64, ls.pdf as f64) < 1e-5);
        };
        mean_inverse_pdf_is_the_solid_angle(&mut fam, &scene, (p, draw), &mut s, check);
    }
    fam.finish();
}

/// Behind the one-sided lamp and in its plane there is nothing to draw, by either draw, and
/// the density of a point seen from there is zero.
#[test]
fn behind_the_lamp_nothing_is_drawn() {
    let scene = lamp();
    let light = &scene.lights[0];
    let Light::Area { prims, .. } = light else {
        panic!("the lamp is an area light")
    };
    let u = (Vec2::new(0.3, 0.6), 0.5);
    for p in [
        Vec3::new(0.1, 1.2, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.2, 1.0, 0.5),
    ] {
        for draw in [Area, SolidAngleNear] {
            assert!(
                light.sample_li(&scene.prims, p, u, draw).is_none(),
                "{draw:?} at {p}"
            );
            let on = (Vec3::new(-0.3, 1.0, 0.1), Vec3::NEG_Y, prims[0]);
            assert_eq!(
                light.pdf_li(&scene.prims, p, on, draw),
                0.0,
                "{draw:?} at {p}"
            );
        }
    }
}

/// A lamp of several quads (a box, six faces of area 1) picks a face by area, then draws on
/// it: from above its top face, the top face's points have the density (1/6) / Omega, the
/// face's share times its own solid angle's density, and `pdf_li` agrees; the side faces,
/// seen from behind, give nothing.
#[test]
fn a_lamp_of_several_quads_draws_each_by_its_share() {
    let text = format!(
        "{CAMERA}{}",
        r#"
[[shapes]]
type = "box"
min = [-0.5, -0.5, -0.5]
max = [0.5, 0.5, 0.5]
emission = [1.0, 1.0, 1.0]
"#
    );
    let scene =
        Scene::load(&SceneSource::embedded("box.toml", &text)).unwrap_or_else(|e| panic!("{e}"));
    let light = &scene.lights[0];
    let Light::Area { prims, .. } = light else {
        panic!("the box is an area light")
    };
    assert_eq!(prims.len(), 6);
    let p = DVec3::new(0.1, 0.8, -0.05);
    // the top face at y = 0.5, seen from 0.3 above: the closed form with the height mirrored
    let seen_as = DVec3::new(p.x, HEIGHT - (p.y - 0.5), p.z);
    let omega = solid_angle(seen_as, (-0.5, 0.5), (-0.5, 0.5));
    let mut s = Sampler::new(13, 0, 0);
    let mut drawn = 0u64;
    for _ in 0..600 {
        let u = (s.next_2d(), s.next_f32());
        let Some(ls) = light.sample_li(&scene.prims, p.as_vec3(), u, SolidAngleNear) else {
            continue;
        };
        drawn += 1;
        assert!(
            ls.n.y > 0.99 && (ls.p.y - 0.5).abs() < 1e-5,
            "only the top face faces p"
        );
        assert!(
            relative(ls.pdf as f64, 1.0 / (6.0 * omega)) < 2e-4,
            "pdf {}",
            ls.pdf
        );
        let top = *prims
            .iter()
            .find(|&&id| scene.prims[id as usize].sample_area(Vec2::splat(0.5)).1.y > 0.99)
            .unwrap();
        let back = light.pdf_li(&scene.prims, p.as_vec3(), (ls.p, ls.n, top), SolidAngleNear);
        assert!(relative(back as f64, ls.pdf as f64) < 1e-5);
    }
    let mut fam = Family::new("box lamp: the top face's share");
    fam.binomial("top face drawn", drawn, 600, 1.0 / 6.0);
    fam.finish();
}

/// A mesh lamp of two triangles covering the quad's rectangle: each triangle near the point is
/// drawn by its own spherical triangle after a choice by area. From the axis through the
/// rectangle's centre the two halves subtend half its solid angle each (a half turn about the
/// axis swaps them), so every sample's 1 / pdf is the rectangle's closed form; off the axis the
/// mean of 1 / pdf is, by either draw, and `pdf_li` gives back the density of every point drawn.
#[test]
fn a_lamp_of_two_triangles_draws_each_by_solid_angle_near() {
    let dir = common::cli::scratch("light-point", "triangles");
    let obj = "v -0.5 1 -0.3\nv 0.5 1 -0.3\nv 0.5 1 0.3\nv -0.5 1 0.3\nf 1 2 3\nf 1 3 4\n";
    std::fs::write(dir.join("lamp.obj"), obj).unwrap();
    let text = format!(
        "{CAMERA}{}",
        r#"
[[shapes]]
type = "mesh"
obj = "lamp.obj"
emission = [1.0, 1.0, 1.0]
"#
    );
    let mut src = SceneSource::embedded("tri.toml", &text);
    src.base_dir = dir;
    let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
    let light = &scene.lights[0];
    let Light::Area { prims, .. } = light else {
        panic!("the mesh is an area light")
    };
    assert_eq!(prims.len(), 2);
    // the first triangle is the half below the diagonal z = 0.6 x
    let prim_of = |p: Vec3| prims[usize::from(p.z > 0.6 * p.x)];
    let mut s = Sampler::new(17, 0, 0);
    let on_axis = DVec3::new(0.0, HEIGHT - 0.3, 0.0);
    let omega = solid_angle(on_axis, X, Z);
    for _ in 0..400 {
        let u = (s.next_2d(), s.next_f32());
        let ls = light
            .sample_li(&scene.prims, on_axis.as_vec3(), u, SolidAngleNear)
            .unwrap();
        assert!(
            relative(1.0 / ls.pdf as f64, omega) < 2e-4,
            "1/pdf {} against {omega}",
            1.0 / ls.pdf
        );
    }
    let mut fam = Family::new("two triangles: the mean of 1 / pdf is the solid angle");
    for (r2, sx, sz) in [(0.2, 0.5, 0.3), (0.1, -0.4, 0.2), (0.05, 0.2, -0.6)] {
        let p = point_at(r2, sx, sz);
        for draw in [Area, SolidAngleNear] {
            let check = |ls: &LightSample| {
                let q = ls.p.as_dvec3();
                assert!(
                    (q.y - HEIGHT).abs() < 1e-5
                        && q.x.abs() <= 0.5 + 1e-5
                        && q.z.abs() <= 0.3 + 1e-5
                );
                let at = (ls.p, ls.n, prim_of(ls.p));
                let back = light.pdf_li(&scene.prims, p.as_vec3(), at, draw);
                assert!(
                    relative(back as f64, ls.pdf as f64) < 1e-4,
                    "{draw:?} at {p}: {back} against {}",
                    ls.pdf
                );
            };
            mean_inverse_pdf_is_the_solid_angle(&mut fam, &scene, (p, draw), &mut s, check);
        }
    }
    fam.finish();
}

/// The default is the solid-angle draw (`[render] light_point`).
#[test]
fn the_default_draw_is_by_solid_angle_near() {
    assert_eq!(LightPointDraw::default(), SolidAngleNear);
}
