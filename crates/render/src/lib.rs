//! Pictures of FROctomap files, drawn with `plotters` and written as PNG with `image`:
//!
//! * [`render_map`]: the map at one time seen from above (each column occupied, shaded by
//!   how much of it is occupied, free or unknown), or a horizontal [`View::Slice`]; the
//!   snapshot as observed inside the file's span, the model's prediction outside it
//!   ([`MapTime::choose`]);
//! * [`render_dynamics`]: where the world changes: per column the dominant period of its
//!   modelled voxels (hue) and the fraction of time they are occupied (strength), static
//!   structure in grey;
//! * [`voxel_plot`]: one voxel over time, its observed states and its model's `p(t)`.
//!
//! Maps are drawn from the file one tile at a time: memory is the picture plus one decoded
//! tile. Text needs a TrueType font, found at run time ([`ensure_font`]).
//!
//! ```no_run
//! use froctomap_render::{render_map, MapTime, View, DEFAULT_WIDTH};
//! let reader = froctomap_file::FroctReader::open(std::path::Path::new("office.froct"))?;
//! let when = MapTime::choose(&reader, "2016-01-05T10:00:00Z".parse()?)?;
//! let picture = render_map(&reader, when, View::TopDown, DEFAULT_WIDTH)?;
//! picture.write_png(std::path::Path::new("map.png"), &[reader.path()])?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod dynamics;
mod error;
mod font;
mod grid;
mod map;
mod picture;
mod voxel_plot;

pub use dynamics::{
    dynamic_colour, render_dynamics, MIN_DYNAMIC_HEIGHT, NO_PERIOD, OTHER_PERIODS, PERIOD_HUES,
};
pub use error::RenderError;
pub use font::{ensure_font, register_font, set_fallback_font, FONT_VARIABLE};
pub use map::{
    is_occupied_shade, occupied_shade, render_map, MapTime, View, FREE, OCCUPIED_HIGH,
    OCCUPIED_LOW, TALL_METRES, UNKNOWN,
};
pub use picture::{MapFrame, Picture, DEFAULT_WIDTH, MAX_WIDTH, MIN_WIDTH};
pub use voxel_plot::{voxel_plot, Line, VoxelPlot};
