//! The torus tolerance tables (measured; see the module docs of [`super`]).

use crate::audit::Precision;
use crate::routines::Expect;

/// `torus`: method × precision × class.
pub fn torus(m: usize, _prec: Precision, _class: usize) -> Expect {
    if super::METHODS[m].robust {
        Expect::pass(64)
    } else {
        Expect::ANY
    }
}

/// `torus_normal`: method × precision × class.
pub fn normal(m: usize, _prec: Precision, _class: usize) -> Expect {
    if super::METHODS[m].robust {
        Expect::pass(64)
    } else {
        Expect::ANY
    }
}
