//! Writes the sample environment map `scenes/envmap-sky.exr`: a 128 x 64 latitude-longitude
//! map (Mitsuba 3's convention, `pathspace::scene::envmap`) of a clear sky, blue at the zenith
//! and pale at the horizon, over a dark ground, with a sun 30 degrees high whose few texels
//! carry most of the power, the case importance sampling by luminance is for.
//! Run with `cargo run --release --example envmap_sky -- scenes/envmap-sky.exr`.

use glam::{Vec2, Vec3};
use pathspace::image_io::{write_exr, Image, ImageMeta};
use pathspace::scene::envmap::direction_of;

const WIDTH: u32 = 128;
const HEIGHT: u32 = 64;
/// The sun's elevation and azimuth (phi of the map), degrees.
const SUN_ELEVATION: f32 = 30.0;
const SUN_PHI: f32 = 110.0;
/// The sun's angular radius, degrees (inflated from 0.27 so that a few texels show it).
const SUN_RADIUS: f32 = 4.0;
/// The sun's radiance: about six times the sky's irradiance on the ground.
const SUN: Vec3 = Vec3::new(1500.0, 1350.0, 1100.0);

/// The radiance of the sky model towards local direction `d`.
fn sky(d: Vec3) -> Vec3 {
    let (s_phi, c_phi) = SUN_PHI.to_radians().sin_cos();
    let (s_el, c_el) = SUN_ELEVATION.to_radians().sin_cos();
    let sun = Vec3::new(s_phi * c_el, s_el, -c_phi * c_el);
    if d.dot(sun) >= SUN_RADIUS.to_radians().cos() {
        return SUN;
    }
    if d.y < 0.0 {
        // the ground: dark, a little brighter towards the horizon
        return Vec3::new(0.12, 0.10, 0.08) * (1.0 + d.y);
    }
    let horizon = Vec3::new(0.95, 0.97, 1.0);
    let zenith = Vec3::new(0.25, 0.45, 0.95);
    horizon.lerp(zenith, d.y.sqrt()) * 0.8
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "scenes/envmap-sky.exr".into());
    let mut image = Image::new(WIDTH, HEIGHT);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            // the texel centres: u = (x + 1/2) / W, theta = pi y / (H - 1)
            let uv = Vec2::new(
                (x as f32 + 0.5) / WIDTH as f32,
                y as f32 / (HEIGHT - 1) as f32,
            );
            image.pixels[(y * WIDTH + x) as usize] = sky(direction_of(uv).0);
        }
    }
    write_exr(std::path::Path::new(&out), &image, &ImageMeta::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let sun = image.pixels.iter().filter(|&&p| p == SUN).count();
    println!("{out}: {WIDTH} x {HEIGHT}, {sun} sun texels");
}
