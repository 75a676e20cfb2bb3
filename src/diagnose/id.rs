//! The stable name of a catalogue effect, the one thing every room of the diagnosis shares about it.
//!
//! An [`EffectId`] is made only by the effect's own module (`crate::diagnose::effects`) and names an entry
//! of its catalogue list; the catalogue adds the lookups (`EffectId::effect`, `EffectId::parse`, the
//! catalogue order). This file depends on nothing, so the fitting room can name an effect without knowing
//! the catalogue.

use serde::{Serialize, Serializer};

/// The contract's stable name of an effect (`gap-drift`, `dead-zone`, ...), serialised as that string.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EffectId(&'static str);

impl EffectId {
    /// The id of the effect named `name`; for the effect modules' own constants.
    pub(crate) const fn declare(name: &'static str) -> Self {
        Self(name)
    }

    /// The contract's stable name.
    pub fn as_str(self) -> &'static str {
        self.0
    }
}

impl std::fmt::Display for EffectId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

impl Serialize for EffectId {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.0)
    }
}
