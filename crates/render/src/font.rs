//! The font of every picture's text: plotters draws text with `ab_glyph` from a TrueType
//! font registered at run time, so no system font library is linked.

use crate::error::RenderError;
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Where Debian, Fedora and Arch put DejaVu Sans (`fonts-dejavu-core` on Debian).
const CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
];

/// The environment variable naming a `.ttf` file to use instead.
pub const FONT_VARIABLE: &str = "FROCTOMAP_FONT";

/// Registers `bytes` (a TrueType font) as the `sans-serif` family every picture uses. The
/// bytes live for the rest of the process.
pub fn register_font(bytes: Vec<u8>, path: &Path) -> Result<(), RenderError> {
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).map_err(|_| {
        RenderError::BadFont {
            path: path.to_path_buf(),
        }
    })
}

/// A font file to use when neither `$FROCTOMAP_FONT` nor a system DejaVu Sans is there
/// (a copy shipped with a program, e.g. the Python wheel's). Set before the first picture.
static FALLBACK: OnceLock<PathBuf> = OnceLock::new();

/// Names the font file [`ensure_font`] uses when `$FROCTOMAP_FONT` is unset and no system
/// DejaVu Sans is found; only the first call counts.
pub fn set_fallback_font(path: PathBuf) {
    let _ = FALLBACK.set(path);
}

/// Why no font was registered (kept for the process, so not a [`RenderError`]).
#[derive(Debug)]
enum Missing {
    /// `$FROCTOMAP_FONT` names a file that cannot be read or is not a font.
    Given { path: PathBuf, reason: String },
    /// No file of the candidates was a font: the paths tried, joined.
    NotFound(String),
}

/// Makes sure a font is registered: `$FROCTOMAP_FONT` if set (an error if it is not a
/// usable font: the user chose it), else DejaVu Sans where Linux distributions install it,
/// else the fallback ([`set_fallback_font`]). Looked up once per process.
pub fn ensure_font() -> Result<(), RenderError> {
    static FOUND: OnceLock<Result<PathBuf, Missing>> = OnceLock::new();
    let found = FOUND.get_or_init(|| {
        if let Some(path) = std::env::var_os(FONT_VARIABLE).filter(|v| !v.is_empty()) {
            let path = PathBuf::from(path);
            let given = |reason: String| Missing::Given {
                path: path.clone(),
                reason,
            };
            let bytes = std::fs::read(&path).map_err(|e| given(e.to_string()))?;
            register_font(bytes, &path)
                .map_err(|_| given("not a TrueType font the plotter can use".into()))?;
            return Ok(path);
        }
        let mut tried = Vec::new();
        for path in CANDIDATES
            .iter()
            .map(PathBuf::from)
            .chain(FALLBACK.get().cloned())
        {
            if let Ok(bytes) = std::fs::read(&path) {
                if register_font(bytes, &path).is_ok() {
                    return Ok(path);
                }
            }
            tried.push(path.display().to_string());
        }
        Err(Missing::NotFound(tried.join(", ")))
    });
    match found {
        Ok(_) => Ok(()),
        Err(Missing::Given { path, reason }) => Err(RenderError::FontVariable {
            path: path.clone(),
            reason: reason.clone(),
        }),
        Err(Missing::NotFound(tried)) => Err(RenderError::NoFont {
            tried: tried.clone(),
        }),
    }
}
