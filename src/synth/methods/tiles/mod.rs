//! The tile family (paper 001): Wang tiles and rotational Wang tiles, the Wang-tile edge colours
//! and tilings they share, lattice-aligned patch placement, and the exported tile-set format.

pub mod align;
pub mod export;
pub mod rw_tiles;
pub mod wang;
pub mod wang_tiles;
