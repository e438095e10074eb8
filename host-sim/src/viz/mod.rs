//! Pictures a person wants to look at: track trails over the frames, like the classic KLT
//! demo, contact sheets of several frames, and the drawing they are made with.

pub mod canvas;
mod trails;

pub use canvas::contact_sheet;
pub use trails::{id_colour, Trails, TRAIL_LEN};
