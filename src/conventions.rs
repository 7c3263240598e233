//! Conventions used everywhere in pathspace, written once (book: "Conventions of the code").
//!
//! - **Directions at a vertex** both point away from it: `wo` towards where the light goes (the
//!   previous vertex of an eye path, the next of a light path), `wi` towards where it comes from.
//!   A phase function's deflection cosine is therefore `-dot(wo, wi)`; Henyey-Greenstein with
//!   g > 0 scatters forwards (its mean deflection cosine is g, checked by `tests/spec/medium/phase.rs`).
//! - **Paths** run x_0 (on a light) to x_k (on the sensor), as in Pauly et al. sec. 3.
//! - **Normals** are geometric and never flipped by the geometry code: a quad's is
//!   normalize(u x v), a box's and a sphere's point outwards. A shape with an `interior` medium
//!   holds it behind its normal.
//! - **Units**: lengths in scene units, sigma in 1/length, radiance in W/(m^2 sr) per channel.
//! - **Depth** counts scattering vertices (surface or medium) between sensor and light:
//!   `max_depth = 0` is emission seen directly, 1 is single scattering.
//! - **Input files** (scenes, grids, meshes) are read to a stated size at most
//!   ([`read_at_most`]), because a path such as `/dev/zero` or a runaway file must be refused,
//!   not read until the memory runs out.

// ANCHOR: deflection
/// The deflection cosine of a phase function for directions in pathspace's convention.
#[inline]
pub fn deflection_cosine(wo: glam::Vec3, wi: glam::Vec3) -> f32 {
    // ASSIGNMENT: deflection_cosine
    -wo.dot(wi)
    // END ASSIGNMENT
}
// ANCHOR_END: deflection

/// The 64-bit FNV-1a hash of `bytes`: scene texts and the files they read are identified by
/// it (a render's identity, `scene_hash`, `scene_inputs`).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_continue(FNV1A_START, bytes)
}

/// The FNV-1a state before any byte.
pub const FNV1A_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a of `bytes` continued from the state `h` (the hash of data given in parts).
pub fn fnv1a_continue(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// The bytes of the file at `path` if it has at most `limit` of them; a longer file is an
/// `InvalidData` error saying so, found from its length before reading, and so is a device or
/// a pipe (`/dev/zero` never ends), which is not read at all.
pub fn read_at_most(path: &std::path::Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let invalid = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidData, m);
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() && !meta.is_dir() {
        return Err(invalid("is not a regular file (a device or a pipe)".into()));
    }
    let too_long = || {
        invalid(format!(
            "has more than {limit} bytes (the limit of such a file)"
        ))
    };
    if meta.len() > limit {
        return Err(too_long());
    }
    // the length may grow while the file is read: one byte more than the limit tells
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_long());
    }
    Ok(bytes)
}

/// An enumerated option value (a scene file's key and a command-line flag at once), declared
/// once as an enum deriving `clap::ValueEnum`: its variants' names (kebab-case unless renamed)
/// are the spellings the flag lists and the file takes; [`option_value!`](crate::option_value)
/// adds the serde form, so a file's bad value is reported at its key as
/// `unknown WHAT `x` (available: a, b)`.
pub trait OptionValue: clap::ValueEnum + Copy + 'static {
    /// What a value is, in the message that refuses one (e.g. `particle sampler`).
    const WHAT: &'static str;

    /// Its spelling in the file and on the command line.
    fn name(self) -> String {
        let v = self.to_possible_value().expect("every value is named");
        v.get_name().to_string()
    }

    /// Every spelling, in declaration order.
    fn names() -> Vec<String> {
        Self::value_variants().iter().map(|v| v.name()).collect()
    }

    /// The value spelled `s`, or the message that lists the spellings.
    fn parse(s: &str) -> Result<Self, String> {
        Self::from_str(s, false).map_err(|_| {
            let what = Self::WHAT;
            format!(
                "unknown {what} `{s}` (available: {})",
                Self::names().join(", ")
            )
        })
    }
}

/// Implements [`OptionValue`] for an enum deriving `clap::ValueEnum`, with serde's form: its
/// name as a string (`option_value!(ParticleSampler, "particle sampler")`).
#[macro_export]
macro_rules! option_value {
    ($t:ty, $what:literal) => {
        impl $crate::conventions::OptionValue for $t {
            const WHAT: &'static str = $what;
        }
        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(&$crate::conventions::OptionValue::name(*self))
            }
        }
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = <String as serde::Deserialize>::deserialize(d)?;
                <$t as $crate::conventions::OptionValue>::parse(&s)
                    .map_err(serde::de::Error::custom)
            }
        }
    };
}
