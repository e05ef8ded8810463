//! Malformed input gets a clear error that names the file and the problem: never a panic,
//! an abort inside the C++ library, a hang or a huge allocation.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_formats::{FormatError, FormatRegistry, ReadOptions};
use froctomap_octomap_codec::{CodecError, ReadLimits};
use froctomap_octomap_ffi::{OcTree, OctomapError};
use froctomap_test_support::{octomap_fixture, scratch};
use proptest::prelude::*;
use std::path::Path;

const SMALL_FIXTURES: [&str; 6] = [
    "few_voxels.bt",
    "few_voxels.ot",
    "coarse_leaves.bt",
    "coarse_leaves.ot",
    "crlf_comments.bt",
    "legacy_headerless.bt",
];

/// `error` as the front ends print it (its causes after it, each once): a refusal's reason is
/// often the cause of an error that names the file.
fn printed(error: &FormatError) -> String {
    assert_eq!(froctomap_core::said_twice(error), None, "{error:?}");
    froctomap_core::error_message(error)
}

fn read_bytes(name: &str, bytes: &[u8]) -> Result<froctomap_formats::ReadOutcome, FormatError> {
    FormatRegistry::with_default_formats().read_bytes(
        Path::new(name),
        bytes,
        ReadOptions::default(),
    )
}

#[test]
fn every_truncation_of_every_small_fixture_is_a_clear_error() {
    for name in SMALL_FIXTURES {
        let bytes = std::fs::read(octomap_fixture(name)).unwrap();
        for len in 0..bytes.len() {
            let cut = &bytes[..len];
            let err = match read_bytes(name, cut) {
                Err(err) => err,
                Ok(_) => panic!("{name} cut to {len} of {} bytes was accepted", bytes.len()),
            };
            let message = printed(&err);
            assert!(message.starts_with(&format!("{name}: ")), "{message}");
            // Straight through the FFI too: it must refuse before upstream reads garbage.
            assert!(OcTree::read(cut).is_err(), "{name} cut to {len}");
        }
    }
}

#[test]
fn truncated_body_names_the_offset() {
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    let err = printed(&read_bytes("few_voxels.bt", &bytes[..bytes.len() - 1]).unwrap_err());
    assert!(err.contains("truncated"), "{err}");
    assert!(
        err.contains(&format!("offset {}", bytes.len() - 2)),
        "{err}"
    );
}

#[test]
fn empty_file_is_reported_as_empty() {
    let dir = scratch();
    let path = dir.path().join("nothing.bt");
    std::fs::write(&path, b"").unwrap();
    let err = printed(
        &FormatRegistry::with_default_formats()
            .read_file(&path, ReadOptions::default())
            .unwrap_err(),
    );
    assert!(err.contains("nothing.bt") && err.contains("empty"), "{err}");
    assert!(matches!(
        OcTree::read(b""),
        Err(OctomapError::Malformed(CodecError::Empty))
    ));
}

#[test]
fn missing_file_is_reported_with_its_path() {
    let err = printed(
        &FormatRegistry::with_default_formats()
            .read_file(Path::new("/no/such/dir/map.bt"), ReadOptions::default())
            .unwrap_err(),
    );
    assert!(
        err.contains("/no/such/dir/map.bt") && err.contains("cannot read"),
        "{err}"
    );
}

#[test]
fn unrecognised_content_says_what_it_starts_with() {
    let err = printed(&read_bytes("photo.bt", b"\x89PNG\r\n\x1a\n....").unwrap_err());
    assert!(
        err.contains("photo.bt") && err.contains("not a map file"),
        "{err}"
    );
    assert!(err.contains("PNG"), "{err}");
}

#[test]
fn wrong_size_header_is_tolerated_with_a_warning_or_skips_the_body_when_zero() {
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    let text = String::from_utf8_lossy(&bytes).into_owned();
    assert!(text.contains("size 37\n"));
    let wrong = |size: &str| {
        let mut patched = bytes.clone();
        let at = text.find("size 37").unwrap();
        patched.splice(at..at + 7, size.bytes());
        patched
    };
    let bigger = read_bytes("few_voxels.bt", &wrong("size 99")).unwrap();
    assert_eq!(bigger.map.snapshot.leaves().len(), 5);
    assert!(bigger
        .map
        .warnings
        .iter()
        .any(|w| w.contains("size 99") && w.contains("37 nodes")));
    // `size 0` makes upstream skip the data: the map is empty, and we say why.
    let zero = read_bytes("few_voxels.bt", &wrong("size 0")).unwrap();
    assert!(zero.map.snapshot.is_empty());
    assert!(zero
        .map
        .warnings
        .iter()
        .any(|w| w.contains("size 0") && w.contains("ignored")));
    // A size that is not a number is malformed.
    let err = printed(&read_bytes("few_voxels.bt", &wrong("size x7")).unwrap_err());
    assert!(
        err.contains("few_voxels.bt") && err.contains("size"),
        "{err}"
    );
}

#[test]
fn bt_renamed_ot_is_read_by_content_with_a_warning_but_a_forced_format_is_an_error() {
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    let detected = read_bytes("renamed.ot", &bytes).unwrap();
    assert_eq!(detected.format.name, "bt");
    assert!(detected
        .map
        .warnings
        .iter()
        .any(|w| w.contains(".bt file despite the file name")));
    let forced = printed(
        &FormatRegistry::with_default_formats()
            .read_bytes(
                Path::new("renamed.ot"),
                &bytes,
                ReadOptions {
                    format: Some("ot"),
                    ..Default::default()
                },
            )
            .unwrap_err(),
    );
    assert!(
        forced.starts_with("renamed.ot: not an OctoMap .ot file"),
        "{forced}"
    );
    assert!(forced.contains("this is a .bt file"), "{forced}");
    // And the other way round, straight through the FFI.
    let ot = std::fs::read(octomap_fixture("few_voxels.ot")).unwrap();
    let err = OcTree::read_binary(&ot).unwrap_err().to_string();
    assert!(err.contains("this is a .ot file"), "{err}");
}

fn bt_header(size: usize) -> Vec<u8> {
    format!("# Octomap OcTree binary file\nid OcTree\nsize {size}\nres 0.1\ndata\n").into_bytes()
}

/// Upstream recurses without bound; a chain of "has children" codes deeper than 16 levels
/// would build a corrupt tree (or exhaust the stack). It must be refused first.
#[test]
fn trees_deeper_than_sixteen_levels_are_refused() {
    let mut file = bt_header(18);
    for _ in 0..17 {
        file.extend([0b11, 0]);
    }
    file.extend([0b10, 0]);
    let err = OcTree::read_binary(&file).unwrap_err();
    assert!(
        matches!(err, OctomapError::Malformed(CodecError::TooDeep { .. })),
        "{err}"
    );
    // A million-level chain is refused just as quickly (no recursion into it).
    let mut deep = bt_header(1_000_001);
    deep.extend(std::iter::repeat_n([0b11u8, 0], 1_000_000).flatten());
    assert!(OcTree::read_binary(&deep).is_err());
    let mut ot = b"# Octomap OcTree file\nid OcTree\nsize 18\nres 0.1\ndata\n".to_vec();
    for _ in 0..18 {
        ot.extend(1.0f32.to_le_bytes());
        ot.push(1);
    }
    assert!(matches!(
        OcTree::read_full(&ot),
        Err(OctomapError::Malformed(CodecError::TooDeep { .. }))
    ));
}

#[test]
fn node_limit_is_enforced_before_the_library_allocates() {
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    let err = OcTree::read_binary_with_limits(&bytes, ReadLimits { max_nodes: 10 }).unwrap_err();
    assert!(
        matches!(
            err,
            OctomapError::Malformed(CodecError::TooManyNodes { limit: 10 })
        ),
        "{err}"
    );
    assert!(OcTree::read_binary_with_limits(&bytes, ReadLimits { max_nodes: 37 }).is_ok());
}

#[test]
fn unsupported_tree_types_are_named() {
    let ot = std::fs::read(octomap_fixture("few_voxels.ot")).unwrap();
    // A `.ot` of a type whose node layout froctomap does not know is refused by name.
    let at = ot.windows(9).position(|w| w == b"id OcTree").unwrap() + 9;
    let stamped = [&ot[..at], b"Stamped", &ot[at..]].concat();
    let err = printed(&read_bytes("stamped.ot", &stamped).unwrap_err());
    assert!(
        err.contains("stamped.ot") && err.contains("OcTreeStamped"),
        "{err}"
    );
}

/// Every outcome of a random mutation is either a map both readers agree on or an error.
fn agree_or_fail(bytes: &[u8]) {
    let upstream = OcTree::read(bytes);
    let native = froctomap_octomap_codec::decode(bytes, None, ReadLimits::default());
    match (upstream, native) {
        (Ok(loaded), Ok(decoded)) => {
            let snapshot = loaded.tree.to_snapshot();
            let decoded =
                froctomap_core::Snapshot::from_leaves(decoded.header.resolution, decoded.leaves);
            match (snapshot, decoded) {
                (Ok(a), Ok(b)) => assert_eq!(a, b),
                (Err(_), Err(_)) => {}
                (a, b) => panic!("readers disagree: upstream {a:?}, native {b:?}"),
            }
        }
        (Err(_), Err(_)) => {}
        (a, b) => panic!(
            "readers disagree: upstream ok={}, native ok={}",
            a.is_ok(),
            b.is_ok()
        ),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_are_rejected_cleanly(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        prop_assert!(read_bytes("random.bin", &bytes).is_err() || bytes.starts_with(b"# Octomap"));
        agree_or_fail(&bytes);
    }

    #[test]
    fn random_bodies_after_a_valid_header_never_crash(
        body in proptest::collection::vec(any::<u8>(), 0..200),
        full in any::<bool>(),
        size in 1usize..100,
    ) {
        let mut bytes = if full {
            format!("# Octomap OcTree file\nid OcTree\nsize {size}\nres 0.05\ndata\n").into_bytes()
        } else {
            bt_header(size)
        };
        bytes.extend(body);
        agree_or_fail(&bytes);
    }

    #[test]
    fn bit_flips_in_fixtures_never_crash(
        which in 0..SMALL_FIXTURES.len(),
        flips in proptest::collection::vec((any::<proptest::sample::Index>(), 0u8..8), 1..4),
    ) {
        let mut bytes = std::fs::read(octomap_fixture(SMALL_FIXTURES[which])).unwrap();
        for (index, bit) in flips {
            let i = index.index(bytes.len());
            bytes[i] ^= 1 << bit;
        }
        agree_or_fail(&bytes);
    }
}
