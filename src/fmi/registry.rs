//! The FMUs one binary serves, and the seam through which they register.
//!
//! A protocol layer picks the model by the GUID (FMI 2.0) or instantiation token (FMI 3.0) the importer
//! passes, through [`new_instance`](super::boundary::new_instance), so that neither layer names a model. The
//! core declares the seam, the [`Fmus`] trait; the crate's adapters implement it once, for [`Binary`]
//! (`crate::fmus`), and nothing in the core or the layers names them or their module: the compiler finds the
//! one implementation.

use super::adapter::{Adapter, Slave};
use super::model::Model;

/// One registered FMU: its identity and how to make a fresh instance of its model.
pub struct Entry {
    pub guid: &'static str,
    pub identifier: &'static str,
    make: fn() -> Box<dyn Slave>,
}

fn make<M: Model>() -> Box<dyn Slave> {
    Box::new(Adapter::<M>::new())
}

impl Entry {
    /// The entry of model `M`.
    pub const fn of<M: Model>() -> Self {
        Self {
            guid: M::GUID,
            identifier: M::MODEL_IDENTIFIER,
            make: make::<M>,
        }
    }
}

/// The FMUs of a binary.
pub struct Registry(&'static [Entry]);

impl Registry {
    pub const fn new(entries: &'static [Entry]) -> Self {
        Self(entries)
    }

    pub fn entries(&self) -> &'static [Entry] {
        self.0
    }

    /// A fresh model of the FMU whose GUID is `guid`, or why there is none: `what` names the argument
    /// (`fmuGUID`, `instantiationToken`), and the message lists the GUIDs this binary knows.
    pub fn instantiate(&self, guid: &str, what: &str) -> Result<Box<dyn Slave>, String> {
        match self.0.iter().find(|e| e.guid == guid) {
            Some(e) => Ok((e.make)()),
            None => {
                let known: Vec<String> = self
                    .0
                    .iter()
                    .map(|e| format!("{} ({})", e.guid, e.identifier))
                    .collect();
                Err(format!(
                    "{what} {guid} matches none of this binary's FMUs ({}): the modelDescription.xml and \
                     the binary do not belong together",
                    known.join(", ")
                ))
            }
        }
    }
}

/// The seam: the FMUs a binary serves. Declared here, implemented once for [`Binary`] by the crate that holds
/// the models; a binary without an implementation does not compile.
pub trait Fmus {
    fn registry() -> &'static Registry;
}

/// The binary being built, as the seam sees it (a type with no values: only its [`Fmus`] implementation
/// matters).
pub enum Binary {}

/// The FMUs of this binary (through the seam, [`Fmus`]).
pub fn registry() -> &'static Registry {
    <Binary as Fmus>::registry()
}
