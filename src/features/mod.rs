//! Features of a coupler curve (domain.md §5): straight segments, pseudo-arcs, double
//! points, symmetry and cognates. Pure: no I/O, no global state.

pub mod fit;
