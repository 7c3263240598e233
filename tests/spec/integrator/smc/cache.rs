//! The radiance cache of Pegoraro, Wald, Parker 2008 (sec. 4.1-4.3): the (s, t) grid, the
//! B-spline control variate and its maintained integral G, the tree of partial sums, and the
//! pdf of an octree leaf after writes and refinements (inheritance).
//! Book: "SMC: the radiance cache".

use crate::common;

use common::sampler;
use common::stats::Family;
use glam::{Vec2, Vec3};
use pathspace::integrator::smc::bspline::Coefficients;
use pathspace::integrator::smc::cache::RadianceCache;
use pathspace::integrator::smc::grid::Grid;
use pathspace::integrator::smc::partial_sums::{PartialSums, PartialSumsError};
use pathspace::integrator::smc::{ControlVariate, Octree, Record};
use pathspace::math::warp;
use pathspace::spectrum::Rgb;

/// Grids from the root to a few refinements.
fn grids() -> Vec<Grid> {
    let mut g = Grid::ROOT;
    let mut out = vec![g];
    for _ in 0..4 {
        g = g.refined();
        out.push(g);
    }
    out
}

fn random_coefficients(grid: Grid, seed: u64) -> Coefficients {
    let mut s = sampler(seed, grid.cells() as u64);
    let values = (0..grid.cells())
        .map(|_| Rgb::new(s.next_f32(), 2.0 * s.next_f32(), s.next_f32() - 0.5))
        .collect();
    Coefficients::from_values(grid, values).unwrap()
}

#[test]
fn st_and_direction_are_inverse_and_cells_have_equal_solid_angle() {
    let mut s = sampler(1, 0);
    for _ in 0..1000 {
        let w = warp::uniform_sphere(s.next_2d());
        let back = Grid::direction(Grid::st(w));
        assert!((back - w).length() < 1e-5, "{w} -> {back}");
    }
    // uniform directions fall in every cell with probability 1 / N: chi-square
    let mut fam = Family::new("smc cache: cells of equal solid angle");
    for grid in grids().into_iter().take(4) {
        let n = 20_000u64;
        let mut counts = vec![0u64; grid.cells()];
        for _ in 0..n {
            counts[grid.cell_of_direction(warp::uniform_sphere(s.next_2d()))] += 1;
        }
        let expected = vec![n as f64 / grid.cells() as f64; grid.cells()];
        fam.chi_square(&format!("cells of {grid:?}"), &counts, &expected);
        // and a direction sampled inside a cell lies in it
        for cell in 0..grid.cells() {
            let w = grid.sample_in_cell(cell, s.next_2d());
            assert_eq!(grid.cell_of_direction(w), cell);
        }
    }
    fam.finish();
}

#[test]
fn order1_reconstruction_interpolates_the_coefficients_at_cell_centres() {
    for grid in grids() {
        let c = random_coefficients(grid, 2);
        for k in 0..grid.cells() {
            let (i, j) = (k % grid.n_s as usize, k / grid.n_s as usize);
            let st = Vec2::new(
                (i as f32 + 0.5) / grid.n_s as f32,
                (j as f32 + 0.5) / grid.n_t as f32,
            );
            let v = c.eval_order1(st);
            assert!(
                (v - c.get(k)).abs().max_element() < 1e-5,
                "{grid:?}, the centre of cell {k}: got {v}, expected its coefficient {}",
                c.get(k)
            );
        }
    }
}

/// The spherical integral of the reconstruction, int L~ / (4 pi) d omega = int int L~ ds dt,
/// by the midpoint rule on a grid 16 times finer than the cells (exact for a piecewise linear
/// function whose breaks lie on the fine grid's edges, up to f32 rounding).
fn integral_by_quadrature(c: &Coefficients, order1: bool) -> Rgb {
    let (ms, mt) = (c.grid.n_s as usize * 16, c.grid.n_t as usize * 16);
    let mut sum = [0.0f64; 3];
    for j in 0..mt {
        for i in 0..ms {
            let st = Vec2::new((i as f32 + 0.5) / ms as f32, (j as f32 + 0.5) / mt as f32);
            let v = if order1 {
                c.eval_order1(st)
            } else {
                c.eval_order0(st)
            };
            for k in 0..3 {
                sum[k] += v[k] as f64;
            }
        }
    }
    let n = (ms * mt) as f64;
    Rgb::new(
        (sum[0] / n) as f32,
        (sum[1] / n) as f32,
        (sum[2] / n) as f32,
    )
}

#[test]
fn the_maintained_integral_equals_the_integral_of_either_reconstruction() {
    for (seed, grid) in grids().into_iter().enumerate() {
        let mut c = random_coefficients(grid, 3 + seed as u64);
        // also after O(1) updates of single cells
        let mut s = sampler(4, seed as u64);
        for _ in 0..50 {
            let k = s.next_index(grid.cells());
            c.set(k, Rgb::new(s.next_f32(), s.next_f32() * 3.0, -s.next_f32()));
        }
        let g = c.integral_isotropic();
        for order1 in [false, true] {
            let q = integral_by_quadrature(&c, order1);
            assert!(
                (q - g).abs().max_element() < 1e-4,
                "{grid:?} order1={order1}: quadrature {q} vs maintained G {g}"
            );
        }
    }
}

/// The reconstruction is bilinear between cell centres and periodic in s (the azimuth): halfway
/// between two centres of a row it is their mean, and across the seam s = 0 = 1 it joins the
/// last column to the first (a clamped s would hold the last column's value there).
#[test]
fn order1_reconstruction_is_bilinear_and_periodic_in_s() {
    for grid in grids() {
        let c = random_coefficients(grid, 3);
        let (n_s, n_t) = (grid.n_s as usize, grid.n_t as usize);
        for j in 0..n_t {
            let t = (j as f32 + 0.5) / n_t as f32;
            for i in 0..n_s {
                let next = (i + 1) % n_s;
                // the midpoint between centre i and centre i + 1 (across the seam for the last)
                let s_mid = ((i as f32 + 1.0) / n_s as f32).rem_euclid(1.0);
                let got = c.eval_order1(Vec2::new(s_mid, t));
                let expected = (c.get(j * n_s + i) + c.get(j * n_s + next)) * 0.5;
                assert!(
                    (got - expected).abs().max_element() < 1e-5,
                    "{grid:?} row {j}, between columns {i} and {next} (s = {s_mid}): got {got}, \
                     expected {expected}"
                );
            }
            let (a, b) = (
                c.eval_order1(Vec2::new(0.0, t)),
                c.eval_order1(Vec2::new(1.0 - 1e-7, t)),
            );
            assert!(
                (a - b).abs().max_element() < 1e-4,
                "{grid:?} row {j}: at s = 0 got {a}, expected the value at s = 1, {b}"
            );
        }
    }
}

#[test]
fn polar_values_remove_the_pole_discontinuity() {
    for grid in grids() {
        let c = random_coefficients(grid, 5);
        for (t, pole) in [(1e-6f32, c.polar_first()), (1.0 - 1e-6, c.polar_last())] {
            // every azimuth converges to the same value at the pole
            for i in 0..64 {
                let v = c.eval_order1(Vec2::new(i as f32 / 64.0, t));
                assert!(
                    (v - pole).abs().max_element() < 1e-3,
                    "{grid:?}: at t = {t}, s = {} gives {v}, pole {pole}",
                    i as f32 / 64.0
                );
            }
        }
        // and the pole value is the mean of the boundary row
        let n_s = grid.n_s as usize;
        let row0: Rgb = (0..n_s).map(|i| c.get(i)).sum::<Rgb>() / n_s as f32;
        assert!((row0 - c.polar_first()).abs().max_element() < 1e-5);
    }
    // the discontinuity exists without them: order 0 differs across s at the pole
    let c = random_coefficients(Grid::ROOT.refined(), 5);
    let a = c.eval_order0(Vec2::new(0.1, 1e-6));
    let b = c.eval_order0(Vec2::new(0.6, 1e-6));
    assert!((a - b).abs().max_element() > 1e-3);
}

#[test]
fn partial_sums_sample_cells_in_proportion_and_keep_the_root_equal_to_the_sum() {
    let mut s = sampler(6, 0);
    let n = 64;
    let mut values: Vec<f64> = (0..n).map(|i| (i % 7) as f64 * s.next_f64()).collect();
    let mut tree = PartialSums::new(&values).unwrap();
    for _ in 0..500 {
        let i = s.next_index(n);
        let v = if s.next_f32() < 0.2 {
            0.0
        } else {
            5.0 * s.next_f64()
        };
        values[i] = v;
        tree.set(i, v);
        let sum: f64 = values.iter().sum();
        assert!(
            (tree.total() - sum).abs() <= 1e-9 * sum.max(1.0),
            "after setting cell {i} to {v}: root got {}, expected the sum {sum}",
            tree.total()
        );
    }
    // every inner node is the sum of its two children
    let nodes = tree.nodes();
    for k in 0..n - 1 {
        assert_eq!(
            nodes[k],
            nodes[2 * k + 1] + nodes[2 * k + 2],
            "node {k}: got {}, expected the sum of its children {} + {}",
            nodes[k],
            nodes[2 * k + 1],
            nodes[2 * k + 2]
        );
    }
    let total: f64 = values.iter().sum();
    let samples = 200_000u64;
    let mut counts = vec![0u64; n];
    for _ in 0..samples {
        let (i, prob) = tree.sample(s.next_f64());
        assert!(values[i] > 0.0, "sampled cell {i}, of value zero");
        assert!(
            (prob - values[i] / total).abs() < 1e-12,
            "probability of cell {i}: got {prob}, expected {}",
            values[i] / total
        );
        counts[i] += 1;
    }
    let expected: Vec<f64> = values.iter().map(|v| v / total * samples as f64).collect();
    let mut fam = Family::new("smc cache: partial sums sampling");
    fam.chi_square("partial sums", &counts, &expected);
    fam.finish();
}

#[test]
fn partial_sums_reject_bad_input() {
    assert_eq!(
        PartialSums::new(&[1.0, 2.0, 3.0]).unwrap_err(),
        PartialSumsError::NotPowerOfTwo(3)
    );
    assert!(matches!(
        PartialSums::new(&[1.0, f64::NAN]),
        Err(PartialSumsError::BadValue { index: 1, .. })
    ));
    assert!(PartialSums::new(&[]).is_err());
}

/// The pdf of a cache as a density over the sphere integrates to one: the sum over cells of
/// density times cell solid angle.
fn pdf_integral(c: &RadianceCache) -> f64 {
    let grid = c.grid();
    (0..grid.cells())
        .map(|k| {
            c.pdf(grid.sample_in_cell(k, Vec2::splat(0.5))) as f64 * grid.cell_solid_angle() as f64
        })
        .sum()
}

#[test]
fn every_pdf_integrates_to_one_and_is_never_zero_after_writes_and_refinements() {
    let mut s = sampler(7, 0);
    // a low threshold refines often; radiance with exact zeros and a hard edge
    let mut octree = Octree::new(
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        4.0,
        1 << 26,
        ControlVariate::Order1,
    );
    for step in 0..40_000 {
        let p = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 2.0 - Vec3::ONE;
        let wi = warp::uniform_sphere(s.next_2d());
        let radiance = if wi.y > 0.3 {
            Rgb::splat(2.0)
        } else {
            Rgb::ZERO
        };
        octree.add_record(&Record {
            p,
            wi,
            radiance,
            phase_value: warp::INV_FOUR_PI,
        });
        if step % 4000 == 3999 {
            for c in octree.caches() {
                if !c.pdf_is_positive() {
                    // only a root that never refined may have a zero cell
                    assert_eq!(octree.stats().nodes, 1);
                    continue;
                }
                let cells = c.grid().cells();
                for k in 0..cells {
                    assert!(
                        c.pdf_coefficient(k) > 0.0,
                        "a zero pdf cell after refinement"
                    );
                }
                // the memory budget's forecast of a cache is what the cache occupies
                assert_eq!(c.bytes(), RadianceCache::bytes_for(cells), "{cells} cells");
                // the mean coefficient (root / N) is the mean over the cells
                let mean = (0..cells).map(|k| c.pdf_coefficient(k)).sum::<f64>() / cells as f64;
                assert!(
                    (c.pdf_coefficient_mean() - mean).abs() <= 1e-9 * mean,
                    "root / N = {} but the cells average {mean}",
                    c.pdf_coefficient_mean()
                );
                let integral = pdf_integral(c);
                assert!(
                    (integral - 1.0).abs() < 1e-4,
                    "pdf integrates to {integral}"
                );
            }
        }
    }
    let stats = octree.stats();
    assert!(stats.max_depth >= 2, "the octree did not refine: {stats}");
}

#[test]
fn the_root_waits_for_both_cells_and_counters_never_round_to_zero() {
    let mut octree = Octree::new(
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        2.0,
        1 << 20,
        ControlVariate::None,
    );
    // records only in the s < 1/2 hemisphere (z > 0 has phi in (0, pi)): cell 1 stays zero
    let w = Vec3::new(0.0, 0.0, 1.0);
    for _ in 0..100 {
        octree.add_record(&Record {
            p: Vec3::ZERO,
            wi: w,
            radiance: Rgb::ONE,
            phase_value: 1.0,
        });
    }
    assert_eq!(
        octree.stats().nodes,
        1,
        "the root refined with a zero pdf cell"
    );
    // one record in the other cell allows the refinement
    octree.add_record(&Record {
        p: Vec3::ZERO,
        wi: -w,
        radiance: Rgb::ONE,
        phase_value: 1.0,
    });
    assert_eq!(octree.stats().nodes, 9);
    for c in octree.caches() {
        for k in 0..c.grid().cells() {
            assert!(c.count(k) >= 1, "a counter was rounded down to zero");
        }
    }
    // cell 0 had 100 records: 100 / 32 = 3 (inherited); cell 1 had 1: max(1, 1 / 32) = 1
    let c = &octree.caches()[1];
    assert_eq!(c.count(c.grid().cell_of_direction(w)), 3);
    assert_eq!(c.count(c.grid().cell_of_direction(-w)), 1);
}

#[test]
fn the_memory_budget_stops_refinement_and_says_so() {
    let mut s = sampler(8, 0);
    let budget = 64 * 1024;
    let mut octree = Octree::new(
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        1.0,
        budget,
        ControlVariate::Order1,
    );
    for _ in 0..50_000 {
        let p = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 2.0 - Vec3::ONE;
        let wi = warp::uniform_sphere(s.next_2d());
        octree.add_record(&Record {
            p,
            wi,
            radiance: Rgb::ONE + wi,
            phase_value: 1.0,
        });
    }
    let stats = octree.stats();
    assert!(stats.budget_reached, "{stats}");
    assert!(stats.bytes <= budget, "{stats}");
    assert!(stats.to_string().contains("memory budget reached"));
}
