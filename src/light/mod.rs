//! Light sources and the direct light they give: the sky and the
//! direct-light stage with its light-sampling library.

pub mod direct;
pub mod lights;
pub mod sky;
pub mod sun_table;
