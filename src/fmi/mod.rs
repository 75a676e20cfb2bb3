//! The protocol-independent core of the FMUs: everything FMI 2.0 and FMI 3.0 co-simulation have in common,
//! for any model.
//!
//! - [`model`]: the [`Model`] trait a model implements to be served; [`adapter`]: its object-safe face;
//!   [`vars`]: the generated variable tables and the checks a value passes before it is set.
//! - [`instance`]: one FMU instance (argument checks, get and set, stepping); [`state`]: its state machine
//!   (the states, and the [`Api`](state::Api) a protocol's function describes itself by); [`timing`]: the
//!   sampled-data timing; [`fmu_state`]: FMU states, their (de)serialisation and the registry of those handed
//!   out; [`log`]: logging.
//! - [`boundary`]: the C boundary: every access to the importer's memory, the panic guard, the bodies the
//!   protocols' functions share; [`status`]: the core's answer, which each layer codes as its own C status.
//! - [`registry`]: the FMUs a binary serves, and the seam through which they register.
//!
//! The layers over the core, `crate::fmi2` and `crate::fmi3`, hold only what is their version's own: the
//! exported functions, the C types and status, the table of which function is allowed in which state. No
//! part of the core or the layers names a model: the models register through [`registry::Fmus`].

pub mod adapter;
pub mod boundary;
pub mod fmu_state;
pub mod instance;
pub mod log;
pub mod model;
pub mod registry;
pub mod state;
pub mod status;
pub mod timing;
pub mod vars;

pub use model::Model;
