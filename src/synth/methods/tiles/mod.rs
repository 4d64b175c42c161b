//! The tile family (paper 001): Wang tiles and rotational Wang tiles, the Wang-tile edge colours
//! and tilings they share, lattice-aligned patch placement, and the exported tile-set format.
//!
//! Imports inside the family go one way, from the methods down (each line imports only from the
//! lines below it):
//!
//! ```text
//! wang_tiles, rw_tiles       the methods, with their typed configs (neither imports the other)
//!   export                   tile-set files: write, load back, render
//!     wang_set, rw_set       the built sets: geometry, tiles, placement and filling
//!       wang                 Wang-tile edge colours and tilings
//! interior                   tiles' own interiors inside a closed seam (imports only common)
//! common, align              shared by both methods: pixel error, patch candidates, `export_tiles`;
//!                            lattice alignment (common imports align and tone)
//!   fit                      tileable fills of sizes that are not whole tiles (imports nothing
//!                            from the family)
//!   tone                     interiors' tone matched to the band around them (imports nothing
//!                            from the family)
//! ```

pub mod align;
pub mod common;
pub mod export;
pub mod fit;
pub mod interior;
pub mod rw_set;
pub mod rw_tiles;
pub mod tone;
pub mod wang;
pub mod wang_set;
pub mod wang_tiles;
