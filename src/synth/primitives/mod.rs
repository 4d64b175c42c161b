//! Image building blocks shared by the methods (docs/methods.md §1), written and tested once.

pub mod block_grid;
pub mod boundary_cut;
pub mod canvas;
pub mod color;
pub mod correlation;
pub mod edges;
pub mod feather;
pub mod graph_cut;
pub mod overlap;
pub mod overlap_search;
pub mod pso;
pub mod pyramid_search;
pub mod shortest_path;
pub mod simd;
pub mod torus;
pub mod zone_ssd;
