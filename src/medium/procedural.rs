//! Density fields on the unit cube of a medium's local coordinates u in [0,1]^3: the analytic
//! ones whose optical depth has a closed form (constant, linear along an axis), used by the
//! tests, and the procedural ones evaluated on the fly (an fBm noise cloud and a smoke plume),
//! each with an upper bound over a box for the majorant grid of delta and ratio tracking.
//!
//! Book: "Table 1: inhomogeneous media" (`book/src/table1-inhomogeneous.md`); executable spec:
//! `tests/spec/medium/heterogeneous.rs`.

use glam::Vec3;

/// The centre of the local unit cube.
const CENTRE: Vec3 = Vec3::splat(0.5);
/// Cloud: radius (local units, the cube's half side is 0.5) beyond which the density is zero.
const CLOUD_RADIUS: f32 = 0.48;
/// Cloud: density = clamp(gain (fbm - bias - falloff (r / radius)^2), 0, 1): dense in the
/// middle (fbm ~ 1/2 there), billowy where the noise beats the radial falloff.
const CLOUD_GAIN: f32 = 4.0;
const CLOUD_BIAS: f32 = 0.2;
const CLOUD_FALLOFF: f32 = 0.5;
/// Plume: Gaussian width at the base and its growth per unit height (local units).
const PLUME_WIDTH_BASE: f32 = 0.04;
const PLUME_WIDTH_GROWTH: f32 = 0.16;
/// Plume: fraction of the density modulated by noise (the rest is the smooth Gaussian).
const PLUME_NOISE: f32 = 0.6;
/// fBm: amplitude ratio and frequency ratio between octaves (1/2 and 2: "1/f" noise).
const FBM_GAIN: f32 = 0.5;
const FBM_LACUNARITY: f32 = 2.0;

/// An axis of the local frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// Parameters of fractional Brownian motion (a sum of value-noise octaves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fbm {
    pub octaves: u32,
    /// Lattice frequency of the first octave, in cells per unit of local coordinates.
    pub frequency: f32,
    pub seed: u32,
}

/// The closed set of analytic and procedural density fields.
#[derive(Clone, Debug, PartialEq)]
pub enum Field {
    /// density = 1 everywhere in the box: the homogeneous medium again.
    Constant,
    /// density = from + (to - from) u[axis]: optical depth in closed form.
    Linear { axis: Axis, from: f32, to: f32 },
    /// A noise cloud: clamp(gain (fbm(u) - bias - falloff (r / R)^2), 0, 1), r the distance
    /// to the centre, zero beyond R.
    Cloud(Fbm),
    /// A smoke plume streaming along +`axis` from the centre of the box's face at the low end
    /// of that axis: a Gaussian of width growing with height, fading towards the far face,
    /// modulated by fBm. `axis = Y` rises; the other axes are the same field with the local
    /// coordinates permuted (so a plume can stream sideways, through a door).
    Plume { fbm: Fbm, axis: Axis },
}

/// A 32-bit integer hash (lowbias32, Wellons) of a lattice point and a seed.
#[inline]
fn hash(x: i32, y: i32, z: i32, seed: u32) -> u32 {
    let mut h = (x as u32)
        .wrapping_mul(0x8da6_b343)
        .wrapping_add((y as u32).wrapping_mul(0xd816_3841))
        .wrapping_add((z as u32).wrapping_mul(0xcb1a_b31f))
        .wrapping_add(seed.wrapping_mul(0x9e37_79b9));
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    h
}

/// Value noise in [0, 1): hashed lattice values, quintic (C2) interpolation.
fn value_noise(p: Vec3, seed: u32) -> f32 {
    let i = p.floor();
    let f = p - i;
    let s = f * f * f * (f * (f * 6.0 - 15.0) + 10.0);
    let (x, y, z) = (i.x as i32, i.y as i32, i.z as i32);
    let v = |dx: i32, dy: i32, dz: i32| {
        (hash(x + dx, y + dy, z + dz, seed) >> 8) as f32 * (1.0 / 16_777_216.0)
    };
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let c00 = lerp(v(0, 0, 0), v(1, 0, 0), s.x);
    let c10 = lerp(v(0, 1, 0), v(1, 1, 0), s.x);
    let c01 = lerp(v(0, 0, 1), v(1, 0, 1), s.x);
    let c11 = lerp(v(0, 1, 1), v(1, 1, 1), s.x);
    lerp(lerp(c00, c10, s.y), lerp(c01, c11, s.y), s.z)
}

impl Fbm {
    // ANCHOR: fbm
    /// fBm normalized to [0, 1): sum of octaves of amplitude gain^o at frequency
    /// frequency lacunarity^o, divided by the sum of the amplitudes.
    pub fn eval(&self, u: Vec3) -> f32 {
        let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, self.frequency);
        for o in 0..self.octaves {
            sum += amp * value_noise(u * freq, self.seed.wrapping_add(o));
            norm += amp;
            amp *= FBM_GAIN;
            freq *= FBM_LACUNARITY;
        }
        sum / norm
    }
    // ANCHOR_END: fbm
}

/// Local coordinates with `axis` moved to y (and y moved to where `axis` was): a permutation,
/// its own inverse, the identity for `Axis::Y`. The plume is written for +y and streams along
/// `axis` by this change of coordinates.
fn plume_frame(u: Vec3, axis: Axis) -> Vec3 {
    match axis {
        Axis::X => Vec3::new(u.y, u.x, u.z),
        Axis::Y => u,
        Axis::Z => Vec3::new(u.x, u.z, u.y),
    }
}

/// Distance from `c` to the nearest point of the box [lo, hi].
fn nearest(c: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    (c.clamp(lo, hi) - c).length()
}

impl Field {
    /// The density at local point `u` (dimensionless; sigma = density times the medium's sigma).
    pub fn eval(&self, u: Vec3) -> f32 {
        match self {
            Field::Constant => 1.0,
            Field::Linear { axis, from, to } => from + (to - from) * u[axis.index()],
            Field::Cloud(fbm) => {
                let r = (u - CENTRE).length();
                if r >= CLOUD_RADIUS {
                    return 0.0;
                }
                let q = r / CLOUD_RADIUS;
                (CLOUD_GAIN * (fbm.eval(u) - CLOUD_BIAS - CLOUD_FALLOFF * q * q)).clamp(0.0, 1.0)
            }
            Field::Plume { fbm, axis } => {
                let u = plume_frame(u, *axis);
                let h = u.y.clamp(0.0, 1.0);
                let rho2 = (u.x - 0.5).powi(2) + (u.z - 0.5).powi(2);
                let w = PLUME_WIDTH_BASE + PLUME_WIDTH_GROWTH * h;
                let envelope = (-rho2 / (2.0 * w * w)).exp() * (1.0 - h);
                envelope * (1.0 - PLUME_NOISE + PLUME_NOISE * fbm.eval(u))
            }
        }
    }

    /// An upper bound of the density over the local box [lo, hi] (the majorant of a block).
    pub fn max_in(&self, lo: Vec3, hi: Vec3) -> f32 {
        match self {
            Field::Constant => 1.0,
            Field::Linear { axis, from, to } => {
                let a = axis.index();
                (from + (to - from) * lo[a]).max(from + (to - from) * hi[a])
            }
            Field::Cloud(_) => {
                // fbm < 1 and r >= the distance to the box's nearest point
                let r = nearest(CENTRE, lo, hi);
                if r >= CLOUD_RADIUS {
                    return 0.0;
                }
                let q = r / CLOUD_RADIUS;
                (CLOUD_GAIN * (1.0 - CLOUD_BIAS - CLOUD_FALLOFF * q * q)).clamp(0.0, 1.0)
            }
            Field::Plume { axis, .. } => {
                // the widest Gaussian (top of the box), the nearest point to the axis, the
                // lowest height; the noise factor is at most 1
                let (lo, hi) = (plume_frame(lo, *axis), plume_frame(hi, *axis));
                let h_lo = lo.y.clamp(0.0, 1.0);
                let w = PLUME_WIDTH_BASE + PLUME_WIDTH_GROWTH * hi.y.clamp(0.0, 1.0);
                let axis = Vec3::new(0.5, 0.0, 0.5);
                let rho = nearest(
                    Vec3::new(axis.x, 0.0, axis.z),
                    Vec3::new(lo.x, 0.0, lo.z),
                    Vec3::new(hi.x, 0.0, hi.z),
                );
                (-rho * rho / (2.0 * w * w)).exp() * (1.0 - h_lo)
            }
        }
    }

    /// True when [`Field::integrate_closed_form`] has an answer (the constant and linear
    /// fields).
    pub fn has_closed_form_integral(&self) -> bool {
        matches!(self, Field::Constant | Field::Linear { .. })
    }

    /// The closed-form integral of the density over t in [ta, tb] along u(t) = u0 + t du, for
    /// the analytic fields; `None` for the procedural ones.
    // ANCHOR: closed_form
    pub fn integrate_closed_form(&self, u0: Vec3, du: Vec3, ta: f32, tb: f32) -> Option<f32> {
        match self {
            Field::Constant => Some(tb - ta),
            Field::Linear { axis, from, to } => {
                // the integral of an affine function is its length times its midpoint value
                let a = axis.index();
                let u_mid = u0[a] + du[a] * 0.5 * (ta + tb);
                Some((tb - ta) * (from + (to - from) * u_mid))
            }
            Field::Cloud(_) | Field::Plume { .. } => None,
        }
    }
    // ANCHOR_END: closed_form
}
