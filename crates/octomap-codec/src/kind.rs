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

/// The tree types whose `.ot` files froctomap reads, by what their nodes store. A `.bt`
/// stores occupancy only, whatever the type; a `.ot` node stores its type's data, which
/// froctomap reads as occupancy (the log-odds) and skips the rest of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum TreeType {
    /// `OcTree`: a node is its `f32` log-odds.
    OcTree,
    /// `ColorOcTree`: a node is its `f32` log-odds then its colour (red, green, blue bytes),
    /// as upstream's `ColorOcTreeNode::writeData` writes it.
    ColorOcTree,
}

impl TreeType {
    /// The type a header's `id` names, if froctomap reads it.
    ///
    /// ```
    /// use froctomap_octomap_codec::TreeType;
    /// assert_eq!(TreeType::from_id("ColorOcTree"), Some(TreeType::ColorOcTree));
    /// assert_eq!(TreeType::from_id("OcTreeStamped"), None);
    /// ```
    pub fn from_id(id: &str) -> Option<Self> {
        match id {
            "OcTree" => Some(TreeType::OcTree),
            "ColorOcTree" => Some(TreeType::ColorOcTree),
            _ => None,
        }
    }

    /// Bytes of one `.ot` node: its data, then the child-mask byte.
    pub const fn full_record_len(self) -> usize {
        match self {
            TreeType::OcTree => 5,
            TreeType::ColorOcTree => 8,
        }
    }
}
