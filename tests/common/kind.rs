//! Which of the two FMUs a test drives, and what it needs to know of it: its GUID, the generated variable
//! table, value references by name.

use backlash::fmi::vars::{Causality, VarInfo, VarType};
use backlash::fmus::{backlash_plant, mrgia_estimator};
use std::ffi::{CStr, CString};
use std::sync::OnceLock;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Plant,
    Estimator,
}

impl Kind {
    pub const ALL: [Kind; 2] = [Kind::Plant, Kind::Estimator];

    /// The FMU's place in [`Kind::ALL`] (for per-FMU counters).
    pub fn idx(self) -> usize {
        self as usize
    }

    /// The GUID (FMI 2.0), which is also the instantiation token (FMI 3.0), as the importer passes it.
    pub fn guid(self) -> &'static CStr {
        static GUIDS: OnceLock<[CString; 2]> = OnceLock::new();
        &GUIDS.get_or_init(|| {
            [backlash_plant::GUID, mrgia_estimator::GUID].map(|g| CString::new(g).unwrap())
        })[self.idx()]
    }

    pub fn variables(self) -> &'static [VarInfo] {
        match self {
            Kind::Plant => &backlash_plant::VARIABLES,
            Kind::Estimator => &mrgia_estimator::VARIABLES,
        }
    }

    pub fn categories(self) -> &'static [&'static str] {
        match self {
            Kind::Plant => backlash_plant::LOG_CATEGORIES,
            Kind::Estimator => mrgia_estimator::LOG_CATEGORIES,
        }
    }

    /// The value reference of the variable `name`.
    pub fn vr(self, name: &str) -> u32 {
        self.variables()
            .iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("{self:?} has no variable {name}"))
            .vr
    }

    /// The value references of the variables of type `ty` and causality `causality`, in table order.
    pub fn vrs(self, ty: VarType, causality: Causality) -> Vec<u32> {
        self.variables()
            .iter()
            .filter(|v| v.ty == ty && v.causality == causality)
            .map(|v| v.vr)
            .collect()
    }

    /// The value references of every variable of type `ty`, in table order.
    pub fn all_of(self, ty: VarType) -> Vec<u32> {
        self.variables()
            .iter()
            .filter(|v| v.ty == ty)
            .map(|v| v.vr)
            .collect()
    }

    /// Whether a variable of type `ty` has the value reference `vr`.
    pub fn known(self, ty: VarType, vr: u32) -> bool {
        self.variables().iter().any(|v| v.vr == vr && v.ty == ty)
    }

    /// A variable of type `ty` to read, if the FMU has one.
    pub fn any(self, ty: VarType) -> Option<u32> {
        self.variables().iter().find(|v| v.ty == ty).map(|v| v.vr)
    }

    /// The first Real input.
    pub fn input(self) -> u32 {
        self.vrs(VarType::Real, Causality::Input)[0]
    }
}
