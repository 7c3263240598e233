//! Enlightened local path sampling (Kristensen 2010, ch. 5), extended to participating media.
//! Book: "Enlightened local path sampling: guiding".

pub mod direction_map;
pub mod guide;
pub mod regions;

pub use direction_map::DirectionMap;
pub use guide::{Deposit, Guide, GuideKind, GuideSettings, GuideStats};
pub use regions::{RegionParams, RegionPoint, Regions};
