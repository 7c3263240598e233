//! The reconstruction filters (`pathspace::film::filter`): Mitsuba 3's radii and defaults, the
//! closed-form integrals against quadrature, the per-pixel normalization of splats (each
//! pixel's weight integrates to 1 over the film), separability and the pixels a sample reaches.
//! Book: "Measuring a renderer" (the film and its filter).

use pathspace::film::{FilterBlock, PixelFilter};
use pathspace::scene::{Scene, SceneSource};

const GAUSSIAN: PixelFilter = PixelFilter::Gaussian { stddev: 0.5 };
const TENT: PixelFilter = PixelFilter::Tent { radius: 1.0 };

/// The filters under test: Mitsuba's defaults and other parameters.
fn filters() -> [PixelFilter; 5] {
    [
        PixelFilter::Box,
        TENT,
        PixelFilter::Tent { radius: 2.5 },
        GAUSSIAN,
        PixelFilter::Gaussian { stddev: 0.3 },
    ]
}

/// The midpoint rule of `f` over [a, b] with `n` steps, and its error bound: the rule's
/// (b - a) h^2 max|f''| / 24 for a function with `f2` = max|f''| on each smooth piece (the
/// pieces' joints, the tent's kinks at 0 and +-r, are on step boundaries), plus the rounding
/// of n additions, n epsilon times the sum.
fn midpoint(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize, f2: f64) -> (f64, f64) {
    let h = (b - a) / n as f64;
    let sum: f64 = (0..n).map(|i| f(a + (i as f64 + 0.5) * h)).sum();
    let rounding = n as f64 * f64::EPSILON * (sum * h).abs();
    (sum * h, (b - a) * h * h * f2 / 24.0 + rounding + 1e-15)
}

/// max |w''|: 0 for the box and tent pieces, 1 / stddev^2 for the gaussian.
fn curvature(f: PixelFilter) -> f64 {
    match f {
        PixelFilter::Gaussian { stddev } => 1.0 / (stddev as f64 * stddev as f64),
        _ => 0.0,
    }
}

/// Mitsuba 3 (plugins `gaussian`, `tent`): the gaussian's support ends at 4 standard
/// deviations, where it reaches 0 (its value minus exp(-8)); the tent's at its radius.
#[test]
fn radii_are_mitsubas() {
    assert_eq!(GAUSSIAN.radius(), 2.0);
    assert_eq!(
        PixelFilter::Gaussian { stddev: 0.3 }.radius(),
        4.0 * 0.3f32 as f64
    );
    assert_eq!(TENT.radius(), 1.0);
    assert_eq!(PixelFilter::Box.radius(), 0.5);
    for f in filters() {
        let r = f.radius();
        assert!(f.eval(r + 1e-9) == 0.0, "{f:?}: nonzero beyond the radius");
        assert!(f.eval(r - 1e-6) > 0.0, "{f:?}: zero inside the radius");
        if !f.is_box() {
            assert!(f.eval(r).abs() < 1e-15, "{f:?}: not 0 at the radius");
        }
    }
    // the gaussian is exp(-x^2 / (2 stddev^2)) shifted down by its value at the radius
    let g = |x: f64| (-2.0 * x * x).exp() - (-8.0f64).exp();
    for x in [0.0, 0.3, 0.5, 1.0, 1.5] {
        assert!((GAUSSIAN.eval(x) - g(x)).abs() < 1e-15, "gaussian at {x}");
    }
    assert_eq!(TENT.eval(0.25), 0.75);
}

/// The defaults of `[camera] filter` are Mitsuba's: tent radius 1, gaussian stddev 0.5.
#[test]
fn scene_defaults_are_mitsubas() {
    let camera = |filter: &str| {
        let text = format!(
            "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 40.0\nresolution = [4, 4]\n{filter}\n"
        );
        let scene = Scene::load(&SceneSource::embedded("t.toml", &text));
        scene
            .map(|s| s.camera.unwrap().filter)
            .map_err(|e| e.to_string())
    };
    assert_eq!(camera(""), Ok(PixelFilter::Box));
    assert_eq!(camera("filter = { type = \"box\" }"), Ok(PixelFilter::Box));
    assert_eq!(camera("filter = { type = \"tent\" }"), Ok(TENT));
    assert_eq!(camera("filter = { type = \"gaussian\" }"), Ok(GAUSSIAN));
    assert_eq!(
        camera("filter = { type = \"gaussian\", stddev = 0.25 }"),
        Ok(PixelFilter::Gaussian { stddev: 0.25 })
    );
    for bad in [
        "filter = { type = \"gaussian\", stddev = 0.0 }",
        "filter = { type = \"tent\", radius = -1.0 }",
        "filter = { type = \"tent\", radius = 100.0 }",
        "filter = { type = \"lanczos\" }",
        "filter = { type = \"gaussian\", radius = 2.0 }",
    ] {
        let e = camera(bad).unwrap_err();
        assert!(e.contains("filter"), "{bad}: {e}");
    }
}

/// The closed-form integral (`primitive`) is the quadrature of `eval` over the support, and at
/// every point inside it.
#[test]
fn closed_form_integrals_match_quadrature() {
    for f in filters() {
        let r = f.radius();
        for t in [-r, -0.7 * r, -0.1, 0.0, 0.4 * r, r] {
            // an even number of steps over [-r, t] puts the tent's kink at 0 on a boundary
            let n = 200_000;
            let (q, bound) = if t > 0.0 {
                let (a, e1) = midpoint(|x| f.eval(x), -r, 0.0, n, curvature(f));
                let (b, e2) = midpoint(|x| f.eval(x), 0.0, t, n, curvature(f));
                (a + b, e1 + e2)
            } else {
                midpoint(|x| f.eval(x), -r, t, n, curvature(f))
            };
            let p = f.primitive(t);
            assert!(
                (p - q).abs() <= bound,
                "{f:?} at {t}: closed form {p}, quadrature {q}"
            );
        }
    }
}

/// As used on a film of n pixels, each pixel's weight w(x_j - u) / N_j integrates to 1 over the
/// film (what a splat deposits is an average of f over the filter, also at the edges).
#[test]
fn each_pixels_splat_weight_integrates_to_one_over_the_film() {
    for f in filters() {
        for n in [1u32, 3, 8] {
            let norms = f.norms(n);
            for (j, nj) in norms.iter().enumerate() {
                let c = j as f64 + 0.5;
                // steps of 1 / 200000 pixel: the tent's and box's kinks fall on boundaries
                let steps = 200_000 * n as usize;
                let (q, bound) = midpoint(|u| f.eval(c - u), 0.0, n as f64, steps, curvature(f));
                assert!(
                    (q / nj - 1.0).abs() <= bound / nj,
                    "{f:?}, pixel {j} of {n}: integral {q}, N {nj}"
                );
            }
            // inside a wide film, N is the integral over the whole support
            let wide = f.norms(64);
            let full = f.primitive(f.radius());
            assert!((wide[32] - full).abs() < 1e-12, "{f:?}");
        }
    }
}

/// A sample's weight at pixel (x, y) is w(dx) w(dy) (separable), over exactly the pixels whose
/// centre is within the radius along both axes.
#[test]
fn block_weights_are_separable_over_the_pixels_within_the_radius() {
    for f in filters().into_iter().filter(|f| !f.is_box()) {
        let mut block = FilterBlock::new(f, (40, 40), 16..32, 16..32);
        let p = glam::Vec2::new(20.3, 17.8);
        block.put(f, p, glam::Vec3::ONE);
        let r = f.radius();
        for y in 0..block.height {
            for x in 0..block.width {
                let (px, py) = ((block.x0 + x) as f64 + 0.5, (block.y0 + y) as f64 + 0.5);
                let (dx, dy) = (px - p.x as f64, py - p.y as f64);
                let want = if dx.abs() <= r && dy.abs() <= r {
                    f.eval(dx) * f.eval(dy)
                } else {
                    0.0
                };
                let got = block.sums[(y * block.width + x) as usize];
                assert_eq!(got[3], want, "{f:?} at ({px}, {py})");
                assert_eq!(got[0], want, "{f:?}: w f with f = 1");
            }
        }
    }
}

/// A tile's block spans the pixels its samples reach, the margin: ceil(r + 1/2) - 1 pixels on
/// each side, clipped to the film.
#[test]
fn the_block_spans_the_tile_and_its_margin() {
    assert_eq!(GAUSSIAN.margin(), 2);
    assert_eq!(TENT.margin(), 1);
    assert_eq!(PixelFilter::Box.margin(), 0);
    let b = FilterBlock::new(GAUSSIAN, (20, 10), 16..20, 0..10);
    assert_eq!((b.x0, b.y0, b.width, b.height), (14, 0, 6, 10));
    // a sample at the far corner of a pixel reaches the margin's last pixel and no further
    for f in filters() {
        let m = f.margin() as i64;
        let reach = f.reach(10.999, -100, 100);
        assert!(
            reach.end - 1 - 10 <= m && 10 - reach.start <= m,
            "{f:?}: {reach:?}"
        );
    }
}
