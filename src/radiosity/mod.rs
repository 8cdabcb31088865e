//! Light transport between surfaces: the form factors, the radiosity
//! solvers, the final gather with its patch lights, and the gather's
//! denoiser.

pub mod denoise;
pub mod form_factors;
pub mod gather;
pub mod patch_lights;
pub mod solve;
