//! The hand-made OctoMap fixtures in `fixtures/octomap/`: their intended content, and how
//! each file is produced (by the upstream library through the FFI, plus hand-edited header
//! variants). `cargo run -p froctomap-e2e-tests --example make_fixtures` rewrites them; the
//! `fixtures` test checks the committed files still match, byte for byte.

use froctomap_core::{Leaf, Snapshot, VoxelKey};
use froctomap_octomap_ffi::OcTree;

const RESOLUTION: f64 = 0.1;
const O: u16 = 32768; // key of the coordinate origin

fn voxel(x: u16, y: u16, z: u16, log_odds: f32) -> Leaf {
    Leaf::voxel(VoxelKey::new(x, y, z), log_odds)
}

fn block(x: u16, y: u16, z: u16, depth: u8, log_odds: f32) -> Leaf {
    Leaf::containing(VoxelKey::new(x, y, z), depth, log_odds)
}

/// Five single voxels around the origin with graded log-odds (three occupied, two free).
pub fn few_voxels() -> Snapshot {
    Snapshot::from_leaves(
        RESOLUTION,
        vec![
            voxel(O, O, O, 0.85),
            voxel(O + 1, O, O, 2.0),
            voxel(O, O + 2, O + 3, 0.405),
            voxel(O - 1, O - 1, O - 1, -0.4),
            voxel(O, O, O + 1, -1.3),
        ],
    )
    .expect("valid fixture leaves")
}

/// Coarse leaves at several depths (8³, 4³ and 2³ voxel cubes) beside single voxels.
pub fn coarse_leaves() -> Snapshot {
    Snapshot::from_leaves(
        RESOLUTION,
        vec![
            block(O, O, O, 13, -2.0),            // 8x8x8 free
            block(O + 8, O, O, 14, 3.5),         // 4x4x4 occupied
            block(O + 8, O + 4, O, 15, -1.0),    // 2x2x2 free
            voxel(O + 12, O, O, 1.5),            // single occupied
            block(O - 8, O - 8, O - 8, 13, 0.2), // 8x8x8 barely occupied
            voxel(O - 9, O, O, -0.1),            // single barely free
        ],
    )
    .expect("valid fixture leaves")
}

/// A fixture file: its name and bytes.
pub struct FixtureFile {
    /// File name under `fixtures/octomap/`.
    pub name: &'static str,
    /// Content.
    pub bytes: Vec<u8>,
}

fn binary(snapshot: &Snapshot) -> Vec<u8> {
    OcTree::from_snapshot(snapshot)
        .and_then(|mut tree| tree.write_binary())
        .expect("upstream writes .bt")
}

fn full(snapshot: &Snapshot) -> Vec<u8> {
    OcTree::from_snapshot(snapshot)
        .and_then(|tree| tree.write_full())
        .expect("upstream writes .ot")
}

/// Splits an upstream-written file into its text header and body.
pub fn split_header(bytes: &[u8]) -> (&[u8], &[u8]) {
    let marker = b"\ndata\n";
    let end = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .expect("upstream header ends with a data line")
        + marker.len();
    bytes.split_at(end)
}

/// Every fixture file, generated.
pub fn generate() -> Vec<FixtureFile> {
    let empty = Snapshot::empty(RESOLUTION).expect("valid resolution");
    let few_bt = binary(&few_voxels());
    let (_, few_body) = split_header(&few_bt);
    let few_nodes = froctomap_octomap_codec::decode(&few_bt, None, Default::default())
        .expect("fixture decodes")
        .node_count;

    let mut size_mismatch = b"# Octomap OcTree binary file\n# written by a ROS script that always says size 1\nid OcTree\nsize 1\nres 0.1\ndata\n".to_vec();
    size_mismatch.extend_from_slice(few_body);

    let mut crlf = format!(
        "# Octomap OcTree binary file (hand-edited)\r\n# CRLF line ends, comments, keywords reordered, an unknown keyword\r\nres 0.1\r\n  # indented comment\r\nmystery 42\r\nid OcTree size {few_nodes}\r\ndata\r\n"
    )
    .into_bytes();
    crlf.extend_from_slice(few_body);

    let mut legacy = 3i32.to_le_bytes().to_vec();
    legacy.extend(RESOLUTION.to_le_bytes());
    legacy.extend(u32::try_from(few_nodes).expect("small").to_le_bytes());
    legacy.extend_from_slice(few_body);

    vec![
        FixtureFile {
            name: "empty.bt",
            bytes: binary(&empty),
        },
        FixtureFile {
            name: "empty.ot",
            bytes: full(&empty),
        },
        FixtureFile {
            name: "few_voxels.bt",
            bytes: few_bt.clone(),
        },
        FixtureFile {
            name: "few_voxels.ot",
            bytes: full(&few_voxels()),
        },
        FixtureFile {
            name: "coarse_leaves.bt",
            bytes: binary(&coarse_leaves()),
        },
        FixtureFile {
            name: "coarse_leaves.ot",
            bytes: full(&coarse_leaves()),
        },
        FixtureFile {
            name: "size_mismatch.bt",
            bytes: size_mismatch,
        },
        FixtureFile {
            name: "crlf_comments.bt",
            bytes: crlf,
        },
        FixtureFile {
            name: "legacy_headerless.bt",
            bytes: legacy,
        },
    ]
}

/// The map a fixture must read as.
pub fn expected_snapshot(name: &str) -> Snapshot {
    let from_bt = |s: Snapshot| s.to_max_likelihood();
    match name {
        "empty.bt" | "empty.ot" => Snapshot::empty(RESOLUTION).expect("valid"),
        "few_voxels.ot" => few_voxels(),
        "coarse_leaves.ot" => coarse_leaves(),
        "few_voxels.bt" | "size_mismatch.bt" | "crlf_comments.bt" | "legacy_headerless.bt" => {
            from_bt(few_voxels())
        }
        "coarse_leaves.bt" => from_bt(coarse_leaves()),
        other => panic!("no expectation for fixture {other}"),
    }
}
