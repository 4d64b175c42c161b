//! The near-regular family (paper 000): co-evolution of lattice texels and its TES baseline.
//! Both place texels on the sample's lattice (t1, t2); the lattice parameters, the texel geometry
//! and the convergence test they share are declared once, in `grid`; the two methods import from
//! it and not from each other.

pub mod coevolution;
pub mod grid;
pub mod tes;
