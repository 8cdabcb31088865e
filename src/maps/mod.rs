//! Lightmap pages from the solved light: the pages themselves, seam
//! stitching and the shadowmask.

pub mod lightmap;
pub mod seams;
pub mod shadowmask;
