//! Fitting: the models the diagnosis fits and how it fits them.
//!
//! - [`model`]: the declared model and the extensions added to it, simulated over a record.
//! - [`problem`]: a record split into a fit part and a held-out part, and the fits on it (the linear model,
//!   the plain backlash model, any extended model from its starts).
//! - [`starts`]: what a candidate's fit starts from (the [`starts::Plan`] an effect returns).
//! - [`orders`]: a structure (orders and delay); [`structure`]: its choice, with the delay and initial state,
//!   when they are not declared.
//! - [`lm`]: the bounded Levenberg-Marquardt fitter, costs, BIC and covariances.
//! - [`pins`]: which parameters a fit holds (the play pinned at a width, the zero-gap model's ties).
//! - [`baseline`]: the best ARX model with an intercept at the record's own rate, the linear baseline the
//!   final model is held against.
//!
//! Nothing here names an effect: an extension's behaviour comes from its effect (`crate::diagnose::effects`).

pub mod baseline;
pub(crate) mod linear_oe;
pub mod lm;
pub mod model;
pub mod operating_point;
pub mod orders;
pub mod pins;
pub mod problem;
pub mod rate;
pub mod starts;
pub mod structure;
