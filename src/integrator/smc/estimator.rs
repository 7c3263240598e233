//! The combined estimator of control variates and importance sampling (Pegoraro, Wald, Parker
//! 2008, eq. 1-3, after Owen and Zhou 2000), and the variants compared in the paper's Fig. 3.
//!
//! eq. (1): with a control variate g of known integral G and a pdf p > 0 wherever f != g,
//!
//!   F = E[(f(X) - g(X)) / p(X)] + G,    F^ = (1/N) sum_i (f(x_i) - g(x_i)) / p(x_i) + G,
//!
//! is unbiased for F = int f, and p should now follow |f - g| rather than f.
//!
//! eq. (2): its standard deviation is sigma[F^] = N^(-1/2) sigma[(f - g) / p]: with static g
//! and p the order of convergence is 1/2, and g, p only translate the log-log error curve.
//!
//! eq. (3): if g and p adapt so that V[(f - g) / p] decreases like N^(-2 alpha) relative to
//! V[f], then sigma[F^] = N^(-1/2 - alpha) sigma[f]: sequential adaptation raises the order of
//! convergence. Every estimate uses a fixed snapshot of g and p (sampled before its own
//! record is merged), so each term stays unbiased given the past and so does their mean.
//! Book: "Sequential Monte Carlo adaptation (Pegoraro et al. 2008)".

use crate::spectrum::Rgb;

/// One sample of the combined estimator of eq. (1): G + (f - g) / p.
// ANCHOR: combined
#[inline]
#[allow(non_snake_case)]
pub fn combined(G: Rgb, f: Rgb, g: Rgb, p: f32) -> Rgb {
    // ASSIGNMENT: combined_estimator
    G + (f - g) / p
    // END ASSIGNMENT
}
// ANCHOR_END: combined

/// The order of convergence of eq. (3) when V[(f - g) / p] decreases with order 2 alpha.
pub fn convergence_order(alpha: f64) -> f64 {
    0.5 + alpha
}

/// The importance sampling of the in-scattering integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportanceSampling {
    /// `is0`: no adaptive pdf, the phase function is sampled (uniform for isotropic media;
    /// "MCMC phase function importance sampling" of [PWP08 Fig. 5 d]).
    Phase,
    /// `is1`: the cache's order-0 (piecewise constant) pdf [PWP08 sec. 4.2].
    Order0,
}

/// The control variate of the in-scattering integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ControlVariate {
    /// `cv0`: g = 0, G = 0.
    None,
    /// `cv1`: order-0 (piecewise constant) B-spline reconstruction.
    Order0,
    /// `cv2`: order-1 (piecewise linear) B-spline reconstruction with polar values.
    Order1,
}

/// A combination compared in [PWP08 Fig. 3]: `is1_cv2` is the proposed method, `is0_cv0`
/// plain Monte Carlo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Variant {
    pub is: ImportanceSampling,
    pub cv: ControlVariate,
}

impl Variant {
    /// The proposed method.
    pub const SMC: Variant = Variant {
        is: ImportanceSampling::Order0,
        cv: ControlVariate::Order1,
    };

    /// The names of [`Variant::ALL`], in its order (the command line lists them).
    pub const NAMES: [&'static str; 6] = [
        "is0_cv0", "is0_cv1", "is0_cv2", "is1_cv0", "is1_cv1", "is1_cv2",
    ];

    /// All six combinations.
    pub const ALL: [Variant; 6] = {
        use ControlVariate as C;
        use ImportanceSampling as I;
        [
            Variant {
                is: I::Phase,
                cv: C::None,
            },
            Variant {
                is: I::Phase,
                cv: C::Order0,
            },
            Variant {
                is: I::Phase,
                cv: C::Order1,
            },
            Variant {
                is: I::Order0,
                cv: C::None,
            },
            Variant {
                is: I::Order0,
                cv: C::Order0,
            },
            Variant {
                is: I::Order0,
                cv: C::Order1,
            },
        ]
    };

    /// The paper's name, e.g. `is1_cv2`.
    pub fn name(self) -> String {
        let is = match self.is {
            ImportanceSampling::Phase => 0,
            ImportanceSampling::Order0 => 1,
        };
        let cv = match self.cv {
            ControlVariate::None => 0,
            ControlVariate::Order0 => 1,
            ControlVariate::Order1 => 2,
        };
        format!("is{is}_cv{cv}")
    }
}

/// The six variants as `[render.smc] variant` and `--smc-variant` spell them ([`Variant::NAMES`]).
impl clap::ValueEnum for Variant {
    fn value_variants<'a>() -> &'a [Self] {
        &Variant::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let i = Variant::ALL.iter().position(|v| v == self)?;
        Some(clap::builder::PossibleValue::new(Variant::NAMES[i]))
    }
}

crate::option_value!(Variant, "SMC variant");
