//! The integration tests, one binary: the `texsyn` command line end to end (pipeline, bad input,
//! lattice, methods' job-level behaviour, report in headless Chromium, tile export, shards and
//! merge, signals, manifests written by earlier versions).

mod advice;
mod bad_input;
mod common;
mod compat;
mod diff;
mod guided;
mod hardening;
mod inpaint;
mod lattice;
mod materials;
mod memory;
mod patch_sampling;
mod pipeline;
mod placement;
mod pyramid;
mod report;
mod samples;
mod shards;
mod signals;
mod synth;
mod tile_export;
mod tile_interiors;
mod tile_tone;
mod tileable;
