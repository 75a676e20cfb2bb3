//! The FMUs one binary serves. Each adapter registers its [`Model`] here (the crate's list is `crate::FMUS`),
//! and a protocol layer picks the model by the GUID (FMI 2.0) or instantiation token (FMI 3.0) the importer
//! passes, so that neither layer names a model.

use super::Model;
use super::instance::{Adapter, Slave};

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
