//! Pictures a person wants to look at: track trails over the frames, like the classic KLT
//! demo, and contact sheets of several frames.

mod canvas;
mod trails;

pub use canvas::{contact_sheet, Canvas};
pub use trails::{id_colour, Trails, TRAIL_LEN};
