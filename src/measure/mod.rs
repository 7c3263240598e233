//! The measuring instrument: error metrics, convergence runs and charts.
//! Book: "Measuring a renderer".

pub mod metrics;
