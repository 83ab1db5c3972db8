//! Which terms of the residual an evaluation adds ([`crate::assembly::Frozen::terms`]).

/// The terms of the residual, each added by its own kernel: an evaluation may leave any of
/// them out ([`crate::assembly::Frozen::terms`]). Only the residual is meant to be read from
/// such an evaluation: the contact results are computed whatever the terms, but elements left
/// out carry their history over and have no stress, as a skipped element does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Terms {
    /// The internal forces of the solid elements (with their material's return map).
    pub solids: bool,
    /// The forces of the discrete springs.
    pub springs: bool,
    /// The normal contact forces and the multipliers' constraint rows.
    pub contact_normal: bool,
    /// The friction forces.
    pub friction: bool,
    /// The external loads: point loads, pressures, and the force on a pushed rigid target.
    pub loads: bool,
}

impl Terms {
    /// Every term: the whole residual.
    pub const ALL: Terms = Terms {
        solids: true,
        springs: true,
        contact_normal: true,
        friction: true,
        loads: true,
    };
    /// No term.
    pub const NONE: Terms = Terms {
        solids: false,
        springs: false,
        contact_normal: false,
        friction: false,
        loads: false,
    };
}

impl Default for Terms {
    fn default() -> Self {
        Terms::ALL
    }
}
