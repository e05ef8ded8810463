//! What can go wrong while drawing.

use std::path::PathBuf;

/// Errors of `froctomap-render`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// Reading the file, resolving a time or guarding an output failed.
    #[error(transparent)]
    Convert(#[from] froctomap_convert::ConvertError),
    /// A tile of the file could not be read.
    #[error(transparent)]
    File(#[from] froctomap_file::FileError),
    /// No font for the picture's text.
    #[error(
        "no TrueType font for the picture's text (tried {tried}); install the Debian package \
         fonts-dejavu-core or set FROCTOMAP_FONT to a .ttf file"
    )]
    NoFont {
        /// The paths tried, joined.
        tried: String,
    },
    /// `$FROCTOMAP_FONT` names a file that is not a usable font.
    #[error(
        "FROCTOMAP_FONT={path}: {reason}; name a .ttf file, or unset it to use the system's font"
    )]
    FontVariable {
        /// The file it names.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A font file is not one the text renderer can use.
    #[error("{path}: not a TrueType font the plotter can use")]
    BadFont {
        /// The font file.
        path: PathBuf,
    },
    /// The plotting library failed.
    #[error("drawing the picture: {message}")]
    Draw {
        /// What it said.
        message: String,
    },
    /// PNG encoding failed.
    #[error("encoding the PNG")]
    Encode {
        /// The encoder's error.
        #[source]
        source: image::ImageError,
    },
    /// Writing the output failed (nothing was left behind).
    #[error(transparent)]
    Write(#[from] froctomap_core::AtomicWriteError),
    /// The file has no cells, so there is no map to draw.
    #[error("{path}: the file holds no cells, there is no map to draw")]
    EmptyMap {
        /// The file.
        path: PathBuf,
    },
    /// A slice height outside the map.
    #[error("--slice z={z} m is outside the map's heights {min:.3} .. {max:.3} m")]
    SliceOutside {
        /// The height asked for.
        z: f64,
        /// The map's lowest point.
        min: f64,
        /// The map's highest point.
        max: f64,
    },
    /// A slice that is not `z=HEIGHT`.
    #[error("--slice {text:?}: expected z=HEIGHT in metres (a horizontal cut), e.g. z=0.5")]
    BadSlice {
        /// What was given.
        text: String,
    },
    /// A picture width outside what is drawn.
    #[error("picture width {width} px: expected {min} ..= {max} px")]
    BadWidth {
        /// What was asked for.
        width: u32,
        /// Narrowest picture.
        min: u32,
        /// Widest picture.
        max: u32,
    },
}

/// Plotters' errors carry the backend's error type; they become text here.
pub(crate) fn draw_error(error: impl std::fmt::Display) -> RenderError {
    RenderError::Draw {
        message: error.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use froctomap_core::said_twice;

    fn io() -> std::io::Error {
        std::io::Error::other("disk full")
    }

    /// Every variant, as its chain prints: no text repeats another of the chain and none is
    /// empty (the wrapped errors of the other crates have their own table tests).
    #[test]
    fn every_error_is_said_once() {
        let path = || PathBuf::from("a.froct");
        let all = [
            RenderError::Convert(froctomap_convert::ConvertError::NoInputs),
            RenderError::File(froctomap_file::FileError::Io {
                path: path(),
                source: io(),
            }),
            RenderError::NoFont {
                tried: "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf".into(),
            },
            RenderError::BadFont {
                path: "font.ttf".into(),
            },
            RenderError::FontVariable {
                path: "notes.txt".into(),
                reason: "not a TrueType font the plotter can use".into(),
            },
            draw_error("the backend refused"),
            RenderError::Encode {
                source: image::ImageError::IoError(io()),
            },
            RenderError::Write(froctomap_core::AtomicWriteError {
                path: "map.png".into(),
                source: io(),
            }),
            RenderError::EmptyMap { path: path() },
            RenderError::SliceOutside {
                z: 9.0,
                min: 0.0,
                max: 2.0,
            },
            RenderError::BadSlice { text: "y=1".into() },
            RenderError::BadWidth {
                width: 1,
                min: 200,
                max: 4000,
            },
        ];
        for e in &all {
            // Fails to compile when a variant is added and not listed above.
            match e {
                RenderError::Convert(_)
                | RenderError::File(_)
                | RenderError::NoFont { .. }
                | RenderError::BadFont { .. }
                | RenderError::FontVariable { .. }
                | RenderError::Draw { .. }
                | RenderError::Encode { .. }
                | RenderError::Write(_)
                | RenderError::EmptyMap { .. }
                | RenderError::SliceOutside { .. }
                | RenderError::BadSlice { .. }
                | RenderError::BadWidth { .. } => {}
            }
            assert_eq!(said_twice(e), None, "{e:?}");
        }
        assert_eq!(
            froctomap_core::error_message(&all[6]),
            "encoding the PNG: disk full"
        );
    }
}
