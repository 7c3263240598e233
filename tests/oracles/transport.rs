//! Oracles for the path tracer: analytic scenes with known answers (Pauly, Kollig, Keller 2000,
//! eq. 3 and 4; the closed forms of the book). Every Monte Carlo check is a comparison of a
//! `Family` (one per test, Holm at the suite's per-test level) of a mean with the standard error
//! and degrees of freedom of its own samples; checks of estimators that have no variance (a
//! directional light seen by a meter) use a float tolerance.

use crate::common;

use common::stats::Family;
use common::{film_mean, meter_mean};
use pathspace::integrator::{IntegratorKind, MeterEstimate, RenderSettings, Renderer, Setup};
use pathspace::scene::{Scene, SceneSource};

fn load(text: &str) -> Scene {
    Scene::load(&SceneSource::embedded("test.toml", text)).unwrap_or_else(|e| panic!("{e}"))
}

/// The scene with its `[render]` settings (the meters' sample counts).
fn load_with(text: &str) -> (Scene, RenderSettings) {
    pathspace::integrator::settings::load(&SceneSource::embedded("test.toml", text))
        .unwrap_or_else(|e| panic!("{e}"))
}

fn meters(
    (scene, settings): &(Scene, RenderSettings),
    spp: u32,
    seed: u64,
    max_depth: Option<u32>,
) -> Vec<MeterEstimate> {
    let setup = Setup {
        scene,
        technique: &pathspace::path::PLAIN,
        settings,
        seed,
        max_depth,
    };
    let mut r = Renderer::prepared(IntegratorKind::Path, &setup).unwrap();
    r.pass(spp, &|| {});
    r.meter_estimates()
}

/// Channel `c` of meter `m` against a closed form.
fn check(fam: &mut Family, name: &str, m: &MeterEstimate, c: usize, truth: f64) {
    let (value, se, dof) = meter_mean(m, c);
    fam.mean_is(name, value, se, dof, truth);
}

/// A slab of thickness 1 between z = 0 and z = -1 with optical thickness `tau` and albedo `a`,
/// under a unit directional light along -z, with meters T (below, facing up) and R (above,
/// facing down).
fn slab(tau: f32, albedo: f32) -> String {
    let medium = format!(
        "type = \"homogeneous\"\nsigma_a = {}\nsigma_s = {}",
        tau * (1.0 - albedo),
        tau * albedo
    );
    common::slab_scene(&medium, 1000.0)
}

/// With albedo 0 nothing scatters: T measures the transmittance e^-tau, R measures nothing.
#[test]
fn slab_unscattered_transmittance_is_exp_minus_tau() {
    for tau in [0.5f32, 1.0, 2.0] {
        let scene = load_with(&slab(tau, 0.0));
        let m = meters(&scene, 8, 11, None);
        let truth = (-(tau as f64)).exp();
        for c in 0..3 {
            // the direct term is one deterministic shadow ray: no variance, float tolerance
            let t = m[0].value[c] as f64;
            assert!(
                (t - truth).abs() <= 1e-5 * truth,
                "T(tau={tau}) = {t}, expected {truth}"
            );
            assert_eq!(
                m[1].value[c], 0.0,
                "R(tau={tau}) must be 0 without scattering"
            );
        }
    }
}

/// Single scattering (max_depth = 1) in a slab under normal incidence, isotropic phase:
/// T1 = (a/2) int_0^1 mu (e^-tau - e^(-tau/mu)) / (1 - mu) dmu,
/// R1 = (a/2) int_0^1 mu (1 - e^(-tau (1 + 1/mu))) / (1 + mu) dmu
/// (integrate the once-scattered radiance of each layer over the hemisphere; see the book).
fn single_scattering_closed_form(tau: f64, a: f64) -> (f64, f64) {
    single_scattering_with_phase(tau, a, |_| 0.5)
}

/// The same for any phase function, given as the density 2 pi f_p(mu) of the deflection cosine
/// mu (forward mu = 1): light scattered once at optical depth t into a direction of cosine mu
/// to the downward normal is transmitted with deflection cosine mu and reflected with -mu, so
/// T1 = a int_0^1 2 pi f_p(mu) mu (e^-tau - e^(-tau/mu)) / (1 - mu) dmu and
/// R1 = a int_0^1 2 pi f_p(-mu) mu (1 - e^(-tau (1 + 1/mu))) / (1 + mu) dmu (isotropic:
/// 2 pi f_p = 1/2, the forms above).
fn single_scattering_with_phase(tau: f64, a: f64, p: impl Fn(f64) -> f64) -> (f64, f64) {
    let n = 200_000;
    let (mut t, mut r) = (0.0, 0.0);
    for i in 0..n {
        let mu = (i as f64 + 0.5) / n as f64;
        t += p(mu) * mu * ((-tau).exp() - (-tau / mu).exp()) / (1.0 - mu);
        r += p(-mu) * mu * (1.0 - (-tau * (1.0 + 1.0 / mu)).exp()) / (1.0 + mu);
    }
    (a * t / n as f64, a * r / n as f64)
}

/// Single scattering in a forward and in a backward Henyey-Greenstein slab: the direction
/// convention of the phase function at the integrator's medium vertices (wo points back along
/// the ray, f_p is forward-peaked for g > 0) decides how much is transmitted and how much
/// reflected. The isotropic closed forms and the white furnace cannot see it: with wo and -wo
/// exchanged every other test here passed.
#[test]
fn anisotropic_slab_single_scattering_matches_closed_form() {
    let mut fam = Family::new("transport: anisotropic slab single scattering");
    for (i, g) in [0.6f64, -0.5].into_iter().enumerate() {
        let (tau, a) = (1.0f64, 0.9f64);
        let text = slab(tau as f32, a as f32).replace(
            "[[shapes]]",
            &format!("phase = {{ type = \"hg\", g = {g} }}\n\n[[shapes]]"),
        );
        assert!(text.contains("type = \"hg\""), "the slab template changed");
        let m = meters(&load_with(&text), 32, 40 + i as u64, Some(1));
        // 2 pi f_HG(mu) = (1 - g^2) / (2 (1 + g^2 - 2 g mu)^(3/2))
        let hg = |mu: f64| (1.0 - g * g) / (2.0 * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
        let (t1, r1) = single_scattering_with_phase(tau, a, hg);
        let direct = (-tau).exp();
        check(&mut fam, &format!("T(g={g})"), &m[0], 0, direct + t1);
        check(&mut fam, &format!("R(g={g})"), &m[1], 0, r1);
    }
    fam.finish();
}

#[test]
fn slab_single_scattering_matches_closed_form() {
    let mut fam = Family::new("transport: slab single scattering");
    for (tau, a) in [(0.1f32, 0.9f32), (1.0, 0.9), (1.0, 0.5)] {
        let scene = load_with(&slab(tau, a));
        let m = meters(&scene, 32, 5, Some(1));
        let (t1, r1) = single_scattering_closed_form(tau as f64, a as f64);
        let direct = (-(tau as f64)).exp();
        check(
            &mut fam,
            &format!("T(tau={tau}, a={a})"),
            &m[0],
            0,
            direct + t1,
        );
        check(&mut fam, &format!("R(tau={tau}, a={a})"), &m[1], 0, r1);
    }
    fam.finish();
}

/// Energy conservation in a conservative slab (albedo 1): what is not transmitted is reflected,
/// T + R = 1 (all orders of scattering, Russian roulette included).
#[test]
fn conservative_slab_conserves_energy() {
    let scene = load_with(&slab(1.0, 1.0));
    let m = meters(&scene, 32, 3, None);
    let (t, st, dt) = meter_mean(&m[0], 0);
    let (r, sr, dr) = meter_mean(&m[1], 0);
    // T and R use independent streams, so their variances add; Welch-Satterthwaite dof
    let (vt, vr) = (st * st, sr * sr);
    let dof = (vt + vr).powi(2) / (vt * vt / dt + vr * vr / dr);
    let mut fam = Family::new("transport: conservative slab");
    fam.mean_is("T + R", t + r, (vt + vr).sqrt(), dof, 1.0);
    fam.finish();
}

/// An irradiance meter under a directional light of irradiance E at angle theta measures
/// E cos(theta) (Lambert's cosine law; one deterministic shadow ray).
#[test]
fn meter_measures_cosine_law() {
    for deg in [0.0f32, 30.0, 60.0, 85.0] {
        let th = deg.to_radians();
        let text = format!(
            r#"
[render]
meter_samples = 64
[[lights]]
type = "directional"
direction = [{dx}, 0.0, {dz}]
irradiance = 2.5
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.5, -0.5, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
"#,
            dx = th.sin(),
            dz = -th.cos()
        );
        let m = meters(&load_with(&text), 1, 1, None);
        let truth = 2.5 * (th as f64).cos();
        let v = m[0].value.x as f64;
        assert!(
            (v - truth).abs() <= 1e-5,
            "E at {deg} deg = {v}, expected {truth}"
        );
    }
}

/// A point light of intensity I at height h above a small meter facing it: E = I / h^2.
#[test]
fn meter_under_point_light_follows_inverse_square() {
    let text = r#"
[render]
meter_samples = 256
[[lights]]
type = "point"
position = [0.0, 0.0, 2.0]
intensity = 8.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.001, -0.001, 0.0]
u = [0.002, 0.0, 0.0]
v = [0.0, 0.002, 0.0]
"#;
    let m = meters(&load_with(text), 1, 1, None);
    let v = m[0].value.x as f64;
    // the meter's extent (1e-3 at distance 2) changes E by less than 1e-6 relative
    assert!((v - 2.0).abs() <= 2e-5, "E = {v}, expected 8 / 2^2 = 2");
}

/// An irradiance meter inside a closed box whose six black walls all emit radiance L inwards
/// sees L in every direction of its hemisphere: E = pi L exactly. Both of the path tracer's
/// strategies reach these lights (next-event estimation and the cosine-sampled continuation
/// that hits a wall), so the estimate is pi L only when the two MIS weights of every direction
/// sum to one: the scattering density the light sample is weighted against must be the
/// continuation's cos / pi. Both strategies are low-variance here, so a percent of bias shows.
#[test]
fn meter_inside_an_emitting_box_measures_pi_l() {
    let mut text = String::from("[render]\nmeter_samples = 65536\n");
    // u x v is the emitting (inner) side of each wall
    for (o, u, v) in [
        ("[-1.0, -1.0, -1.0]", "[0.0, 0.0, 2.0]", "[2.0, 0.0, 0.0]"),
        ("[-1.0, 1.0, -1.0]", "[2.0, 0.0, 0.0]", "[0.0, 0.0, 2.0]"),
        ("[-1.0, -1.0, -1.0]", "[2.0, 0.0, 0.0]", "[0.0, 2.0, 0.0]"),
        ("[-1.0, -1.0, 1.0]", "[0.0, 2.0, 0.0]", "[2.0, 0.0, 0.0]"),
        ("[-1.0, -1.0, -1.0]", "[0.0, 2.0, 0.0]", "[0.0, 0.0, 2.0]"),
        ("[1.0, -1.0, -1.0]", "[0.0, 0.0, 2.0]", "[0.0, 2.0, 0.0]"),
    ] {
        text += &format!(
            "[[shapes]]\ntype = \"quad\"\norigin = {o}\nu = {u}\nv = {v}\nemission = 0.5\n"
        );
    }
    text += r#"
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.1, -0.5, -0.1]
u = [0.0, 0.0, 0.2]
v = [0.2, 0.0, 0.0]
"#;
    let m = meters(&load_with(&text), 1, 5, None);
    let mut fam = Family::new("transport: meter inside an emitting box");
    check(&mut fam, "E = pi L", &m[0], 0, std::f64::consts::PI * 0.5);
    fam.finish();
}

/// Two point lights: the irradiances add, E = I_1 cos_1 / d_1^2 + I_2 cos_2 / d_2^2, whichever
/// light each sample picks (the pick's probability divides the sample, so dropping it halves
/// the estimate or worse).
#[test]
fn meter_under_two_point_lights_adds_their_irradiances() {
    let text = r#"
[render]
meter_samples = 4096
[[lights]]
type = "point"
position = [0.0, 0.0, 2.0]
intensity = 8.0
[[lights]]
type = "point"
position = [1.0, 0.0, 1.0]
intensity = 4.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.001, -0.001, 0.0]
u = [0.002, 0.0, 0.0]
v = [0.0, 0.002, 0.0]
"#;
    let m = meters(&load_with(text), 1, 5, None);
    let mut fam = Family::new("transport: meter under two point lights");
    // 8 / 2^2 from above, 4 cos(45 deg) / 2 from the side
    let truth = 2.0 + 4.0 * std::f64::consts::FRAC_1_SQRT_2 / 2.0;
    check(&mut fam, "E = sum of I cos / d^2", &m[0], 0, truth);
    fam.finish();
}

/// A disk light of radius R and radiance L facing a meter on its axis at distance h subtends a
/// cone of half-angle alpha with sin^2 alpha = R^2 / (h^2 + R^2): E = pi L sin^2 alpha. Both
/// strategies are used (the disk's points sampled by area through the concentric map, and the
/// cosine-sampled continuation hitting the disk), so a wrong area, a non-uniform sampler or a
/// wrong intersection test each moves the estimate.
#[test]
fn meter_under_a_disk_light_measures_pi_l_sin2_alpha() {
    let text = r#"
[render]
meter_samples = 65536
[[shapes]]
type = "disk"
center = [0.0, 1.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.0, 0.5]
emission = 2.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.001, 0.0, -0.001]
u = [0.0, 0.0, 0.002]
v = [0.002, 0.0, 0.0]
"#;
    let m = meters(&load_with(text), 1, 9, None);
    let mut fam = Family::new("transport: meter under a disk light");
    let (r2, h2) = (0.25, 1.0);
    check(
        &mut fam,
        "E = pi L sin^2 alpha",
        &m[0],
        0,
        std::f64::consts::PI * 2.0 * r2 / (h2 + r2),
    );
    fam.finish();
}

/// The image of a point light on the pinhole's film (Pauly et al. eq. 5 with both ends
/// Diracs: no walk from the camera can hit it, so `delta_light_view` splats it): a light of
/// intensity I on the optical axis at distance d puts its irradiance E = I / d^2 into one
/// point of the film, the centre, with the value W_e cos E = E npixels / A_film (W_e integrates
/// to one over a pixel's directions, A_film is the film's area at distance 1). Deterministic.
#[test]
fn point_light_in_view_images_its_irradiance_on_the_film() {
    let text = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 30.0
resolution = [16, 12]

[[lights]]
type = "point"
position = [0.0, 0.0, 1.0]
intensity = 8.0
"#;
    // on the axis, and off it at cosine c to the axis, where W_e cos = npixels / (A_film c^3)
    for (position, centre) in [("[0.0, 0.0, 1.0]", true), ("[0.3, 0.2, 1.0]", false)] {
        let scene = load(&text.replace("[0.0, 0.0, 1.0]", position));
        let cam = scene.camera.as_ref().unwrap();
        let mut sampler = pathspace::math::Sampler::new(1, 0, 0);
        let splats = pathspace::integrator::path::delta_light_view(&scene, &mut sampler);
        assert_eq!(
            splats.len(),
            1,
            "one splat per delta light in view: {splats:?}"
        );
        let (raster, l) = splats[0];
        if centre {
            assert!(
                (raster - glam::Vec2::new(8.0, 6.0)).length() < 1e-4,
                "{raster:?}"
            );
        }
        let pathspace::scene::Light::Point { position: p, .. } = scene.lights[0] else {
            unreachable!()
        };
        let d = (p - cam.eye).as_dvec3();
        let c = d.normalize().dot(cam.forward.as_dvec3());
        let e = 8.0 / d.length_squared();
        let expect = e * (16.0 * 12.0) / (cam.film_area() as f64 * c * c * c);
        for ch in 0..3 {
            let got = l[ch] as f64;
            assert!(
                (got - expect).abs() < 1e-5 * expect,
                "{got} vs W_e cos E = {expect}"
            );
        }
    }
}

/// The white furnace: a conservative medium (albedo 1) inside a null sphere under a uniform
/// environment of radiance 1 is in equilibrium with it, so every pixel is 1.
#[test]
fn white_furnace_renders_one_everywhere() {
    let text = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 30.0
resolution = [16, 16]

[media.white]
type = "homogeneous"
sigma_a = 0.0
sigma_s = 2.0
phase = { type = "hg", g = 0.5 }

[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "null"
interior = "white"

[[lights]]
type = "environment"
radiance = 1.0
"#;
    let scene = load(text);
    let mut r = Renderer::new(&scene, IntegratorKind::Path, 9, None);
    const SPP: u32 = 64;
    r.pass(SPP, &|| {});
    let film = r.film.as_ref().unwrap();
    let img = film.image();
    let var = film.variance_of_mean();
    let mut fam = Family::new("transport: white furnace");
    let (mean, se, dof) = film_mean(film, 0);
    fam.mean_is("furnace image mean", mean, se, dof, 1.0);
    // and every pixel, each with its own samples (Holm shares the level over all 257)
    for (i, (p, v)) in img.pixels.iter().zip(&var.pixels).enumerate() {
        let (x, s) = (p.x as f64, (v.x as f64).sqrt());
        fam.mean_is(&format!("pixel {i}"), x, s, (SPP - 1) as f64, 1.0);
    }
    fam.finish();
}

/// Chromatic media without bias: with a different sigma_t and albedo per channel, the slab's
/// single scattering matches the closed form channel by channel (distances are sampled by one
/// channel with the pdf averaged over channels).
#[test]
fn chromatic_slab_matches_closed_form_per_channel() {
    let sigma_a = [0.1f32, 0.3, 0.6];
    let sigma_s = [0.9f32, 0.5, 0.2];
    let text = slab(1.0, 0.5)
        .replace("sigma_a = 0.5", &format!("sigma_a = {sigma_a:?}"))
        .replace("sigma_s = 0.5", &format!("sigma_s = {sigma_s:?}"));
    assert!(
        text.contains("sigma_a = ["),
        "the slab template changed; update this test"
    );
    let scene = load_with(&text);
    let m = meters(&scene, 32, 17, Some(1));
    let mut fam = Family::new("transport: chromatic slab");
    for c in 0..3 {
        let tau = (sigma_a[c] + sigma_s[c]) as f64;
        let a = sigma_s[c] as f64 / tau;
        let (t1, r1) = single_scattering_closed_form(tau, a);
        check(
            &mut fam,
            &format!("T channel {c}"),
            &m[0],
            c,
            (-tau).exp() + t1,
        );
        check(&mut fam, &format!("R channel {c}"), &m[1], c, r1);
    }
    fam.finish();
}

/// Nested media through null boundaries: a thin slab of a second medium inside the first. The
/// unscattered transmittance below both is exp(-(tau_outer + tau_inner)) exactly, whichever
/// boundaries the shadow ray crosses on the way.
#[test]
fn nested_media_multiply_their_transmittances() {
    let text = r#"
[render]
meter_samples = 64
[media.outer]
type = "homogeneous"
sigma_a = 0.4
sigma_s = 0.0
[media.inner]
type = "homogeneous"
sigma_a = [1.5, 2.0, 2.5]
sigma_s = 0.0
[[shapes]]
type = "box"
min = [-10.0, -10.0, -3.0]
max = [10.0, 10.0, 0.0]
material = "null"
interior = "outer"
[[shapes]]
type = "box"
min = [-5.0, -5.0, -2.0]
max = [5.0, 5.0, -1.5]
material = "null"
interior = "inner"
exterior = "outer"
[[lights]]
type = "directional"
direction = [0.0, 0.0, -1.0]
irradiance = 1.0
[[sensors]]
type = "irradiance_meter"
name = "T"
origin = [-0.5, -0.5, -3.5]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
"#;
    let m = meters(&load_with(text), 1, 1, None);
    for (c, inner) in [1.5f64, 2.0, 2.5].into_iter().enumerate() {
        // outer: 3 units minus the 0.5 the inner box replaces; inner: 0.5 units
        let truth = (-(0.4 * 2.5 + inner * 0.5)).exp();
        let v = m[0].value[c] as f64;
        assert!(
            (v - truth).abs() <= 1e-5 * truth.max(1e-3) + 1e-7,
            "channel {c}: {v} vs {truth}"
        );
    }
}

/// A one-sided area light at x = 0 facing +x, 0.3 from a parallel wall: the door-slit's light
/// and end wall. Seen from the wall point (0.3, 0.25, 1.2) every point of the light lies
/// 67-76 degrees off both normals.
const GRAZING: &str = r#"
[camera]
type = "pinhole"
eye = [2.0, 0.25, 0.6]
look_at = [0.0, 0.25, 0.6]
up = [0.0, 1.0, 0.0]
fov_deg = 60.0
resolution = [8, 8]

[materials.white]
type = "lambert"
albedo = 0.5

[[shapes]]
type = "quad"
origin = [0.3, -1.0, -1.0]
u = [0.0, 3.0, 0.0]
v = [0.0, 0.0, 4.0]
material = "white"

[[shapes]]
type = "quad"
origin = [0.0, 0.0, 0.0]
u = [0.0, 0.5, 0.0]
v = [0.0, 0.0, 0.5]
emission = [1.0, 1.0, 1.0]
"#;

/// An edge between two parallel surfaces that see each other at grazing angles is unoccluded:
/// lifting both ends off their surfaces must not push the query past the target's own surface
/// (it did, beyond 45 degrees, which hid 12% of the door slit from BDPT and MLT).
#[test]
fn grazing_edges_between_parallel_surfaces_are_unoccluded() {
    use glam::Vec3;
    use pathspace::math::Sampler;
    use pathspace::scene::EdgeEnd;
    let scene = load(GRAZING);
    let mut sampler = Sampler::new(1, 0, 0);
    for z in [0.1f32, 0.3, 0.6, 1.0, 1.5, 2.5] {
        // from the light's centre (angle atan(z / 0.3) off both normals) to the wall
        let a = EdgeEnd {
            p: Vec3::new(0.0, 0.25, 0.25),
            n: Vec3::X,
            medium: None,
            in_medium: false,
            prim: None,
            camera: false,
        };
        let b = EdgeEnd {
            p: Vec3::new(0.3, 0.25, 0.25 + z),
            n: Vec3::X,
            medium: None,
            in_medium: false,
            prim: None,
            camera: false,
        };
        for (from, to) in [(a, b), (b, a)] {
            let e = scene.edge(from, to, &mut sampler);
            assert_eq!(
                e.transmittance,
                pathspace::spectrum::Rgb::ONE,
                "edge at {:.0} degrees reported occluded",
                (z / 0.3).atan().to_degrees()
            );
        }
    }
}

/// Next-event estimation from a wall point that sees a parallel light only at grazing angles
/// reproduces the irradiance of the light, integrated by quadrature, within 4 standard errors
/// (the shadow ray once left the lifted origin along the unlifted direction, ended behind the
/// light's surface and found the light itself in the way: 0 instead of E).
#[test]
fn next_event_sees_a_parallel_light_at_grazing_angles() {
    use glam::Vec3;
    use pathspace::math::Sampler;
    let scene = load(GRAZING);
    let p = Vec3::new(0.3, 0.25, 1.2);
    // E = integral of L cos cos' / r^2 over the light (L = 1), midpoint rule on 400 x 400
    let m = 400;
    let h = 0.5 / m as f64;
    let mut truth = 0.0f64;
    for i in 0..m {
        for j in 0..m {
            let q = [0.0, (i as f64 + 0.5) * h, (j as f64 + 0.5) * h];
            let d = [0.3 - q[0], 0.25 - q[1], 1.2 - q[2]];
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            truth += d[0] * d[0] / (r2 * r2) * h * h;
        }
    }
    let n = 20_000;
    let samples: Vec<f64> = (0..n)
        .map(|i| {
            let mut s = Sampler::new(7, i, 0);
            // pdf 0 for the scattering strategy: next-event estimation alone, MIS weight 1
            let l = pathspace::integrator::path::next_event(
                &scene,
                p,
                Some(-Vec3::X),
                |_| None,
                &mut s,
                |wi| (pathspace::spectrum::Rgb::splat(wi.x.abs()), 0.0),
            );
            l.x as f64
        })
        .collect();
    let (mean, se) = common::mean_and_stderr(&samples);
    let mut fam = Family::new("transport: grazing next-event estimation");
    fam.mean_is("irradiance", mean, se, (n - 1) as f64, truth);
    fam.finish();
}

/// A meter just above a large smooth conductor, facing it, under a uniform sky of radiance 1:
/// every direction it sees leaves the metal as sky light reflected once with the weight
/// specular F(cos) of Mitsuba's `conductor`, so E = 2 pi specular int_0^1 F(mu) mu dmu per
/// channel (the sky is the same in every direction: only the Fresnel term shapes it). Gold by
/// Mitsuba's name, with a tint; the integral by Simpson's rule on 2000 intervals.
#[test]
fn meter_over_a_smooth_conductor_under_a_uniform_sky() {
    let text = r#"
[render]
meter_samples = 16384
[materials.gold]
type = "conductor"
material = "Au"
specular = [0.9, 0.7, 0.5]
[[shapes]]
type = "quad"
origin = [-1000.0, 0.0, -1000.0]
u = [0.0, 0.0, 2000.0]
v = [2000.0, 0.0, 0.0]
material = "gold"
[[lights]]
type = "environment"
radiance = 1.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.001, 0.01, -0.001]
u = [0.002, 0.0, 0.0]
v = [0.0, 0.0, 0.002]
"#;
    let m = meters(&load_with(text), 1, 3, None);
    let (eta, k) = pathspace::bsdf::named_conductor::named_conductor("Au").unwrap();
    let specular = [0.9, 0.7, 0.5];
    let mut fam = Family::new("transport: meter over a smooth conductor");
    for c in 0..3 {
        let f = |mu: f64| {
            pathspace::bsdf::conductor::fresnel_complex(mu as f32, eta[c], k[c]) as f64 * mu
        };
        let n = 2000;
        let h = 1.0 / n as f64;
        let simpson: f64 = (0..=n)
            .map(|i| {
                let w = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                w * f(i as f64 * h)
            })
            .sum::<f64>()
            * h
            / 3.0;
        let truth = std::f64::consts::TAU * specular[c] * simpson;
        check(&mut fam, "E = 2 pi s int F mu dmu", &m[0], c, truth);
    }
    fam.finish();
}

/// A meter on the axis of an open cylinder of radius R and length 2H that glows with radiance
/// L inwards (flip_normals), facing the wall: it sees the wall wherever the tangent of the
/// elevation is below H / R, i.e. |d_z| < s = H / sqrt(R^2 + H^2), and the dark open ends
/// elsewhere: E = L int_{|d_z| < s, d_x > 0} d_x dw = 2 L (s sqrt(1 - s^2) + asin s). Light
/// sampling draws the wall's points by area (density 1 / (2 pi R 2H)), the continuation hits
/// it (both roots: from inside, the far one); a wrong area, root or radius moves E. Without the
/// flip the meter sees the tube's back, which is black: E = 0.
#[test]
fn meter_inside_a_glowing_cylinder_sees_its_wall() {
    let scene = |flip: bool| {
        format!(
            r#"
[render]
meter_samples = 65536
[[shapes]]
type = "cylinder"
p0 = [0.0, 0.0, -1.5]
p1 = [0.0, 0.0, 1.5]
radius = 1.0
flip_normals = {flip}
emission = 2.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [0.0, -0.001, -0.001]
u = [0.0, 0.002, 0.0]
v = [0.0, 0.0, 0.002]
"#
        )
    };
    let m = meters(&load_with(&scene(true)), 1, 13, None);
    let (r, h, l) = (1.0f64, 1.5f64, 2.0f64);
    let s = h / (r * r + h * h).sqrt();
    let truth = 2.0 * l * (s * (1.0 - s * s).sqrt() + s.asin());
    let mut fam = Family::new("transport: meter inside a glowing cylinder");
    check(
        &mut fam,
        "E = 2 L (s sqrt(1 - s^2) + asin s)",
        &m[0],
        0,
        truth,
    );
    fam.finish();
    let dark = meters(&load_with(&scene(false)), 1, 13, None);
    assert_eq!(dark[0].value[0], 0.0, "the tube's back side emits nothing");
    // its power, pi L A with A = 2 pi R 2H, whichever side emits
    for flip in [true, false] {
        let sc = load(&scene(flip));
        let power = sc.lights[0].power(sc.radius) as f64;
        let exact = std::f64::consts::PI * l * std::f64::consts::TAU * r * 2.0 * h;
        assert!((power - exact).abs() <= 1e-5 * exact, "{power} vs {exact}");
    }
}
