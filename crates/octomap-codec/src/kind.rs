//! OctoMap's two file layouts and the first lines that name them (shared by the header
//! parser, the encoders and the errors, so none of them depends on another for it).

/// First line of a `.bt` file (matched as a prefix).
pub const BINARY_FIRST_LINE: &str = "# Octomap OcTree binary file";
/// First line of a `.ot` file (matched as a prefix).
pub const FULL_FIRST_LINE: &str = "# Octomap OcTree file";
/// Which of OctoMap's two file layouts a file uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FileKind {
    /// `.bt`: 2 bits of state per child, maximum-likelihood only.
    Binary,
    /// `.ot`: every node's log-odds value and a child mask.
    Full,
}

impl FileKind {
    /// The conventional file extension, without dot.
    pub fn extension(self) -> &'static str {
        match self {
            FileKind::Binary => "bt",
            FileKind::Full => "ot",
        }
    }

    /// The first line that identifies this layout.
    pub fn first_line(self) -> &'static str {
        match self {
            FileKind::Binary => BINARY_FIRST_LINE,
            FileKind::Full => FULL_FIRST_LINE,
        }
    }
}
