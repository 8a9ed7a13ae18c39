//! The core's integration tests, compiled as one test binary: the shared builders
//! (`common`, `bars`) and the core's generic code are compiled and linked once instead of
//! once per file, which takes minutes off the test command. `cargo test -p softrod-core
//! <module>::` runs one file's tests.

mod bars;
mod batch;
mod batch_ends;
mod collocation;
mod collocation_derivatives;
mod common;
mod contact;
mod convergence;
mod dynamics;
mod dynamics_contact;
mod dynamics_ends;
mod dynamics_held_contact;
mod dynamics_laws;
mod dynamics_markers;
mod dynamics_scope;
mod dynamics_sensitivity;
mod dynamics_soft;
mod dynamics_system;
mod dynamics_system_sensitivity;
mod dynamics_taper;
mod dynamics_tendons;
mod end_constraints;
mod exact;
mod follower;
mod friction;
mod friction_batch;
mod friction_system;
mod inverse;
mod inverse_collocation;
mod inverse_tendons;
mod jacobian;
mod laws;
mod linearise;
mod linearise_collocation;
mod linearise_loads;
mod linearise_system;
mod mesh_contact;
mod pcc;
mod pcc_chambers;
mod pcc_fast;
mod pcc_sensitivity;
mod pressure;
mod published;
mod reference_shape;
mod sensitivity;
mod stability;
mod system_sensitivity;
mod taper;
mod tendons;
mod validation;
