//! Fixture-driven tests: every file in `fixtures/octomap/` is a golden file, reads as the map
//! it was made from through both the upstream library and the Rust parser, and (where
//! upstream tools accept it) survives an upstream round trip unchanged.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::Snapshot;
use froctomap_formats::{FormatRegistry, ReadOptions};
use froctomap_octomap_codec::{decode, ReadLimits};
use froctomap_octomap_ffi::OcTree;
use froctomap_test_support::{convert_octree, fixtures, octomap_fixture, scratch};

#[test]
fn committed_fixtures_match_their_generator() {
    let generated = fixtures::generate();
    let dir = froctomap_test_support::fixtures_dir().join("octomap");
    let mut committed: Vec<String> = std::fs::read_dir(&dir)
        .expect("fixtures/octomap exists")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    committed.sort();
    let mut names: Vec<String> = generated.iter().map(|f| f.name.to_string()).collect();
    names.sort();
    assert_eq!(
        committed, names,
        "fixtures/octomap holds exactly the generated files"
    );
    for file in generated {
        let on_disk = std::fs::read(dir.join(file.name)).expect("read fixture");
        assert!(
            on_disk == file.bytes,
            "{} differs from its generator; if the change is intended, run \
             `cargo run -p froctomap-e2e-tests --example make_fixtures` and review the diff",
            file.name
        );
    }
}

fn upstream_snapshot(bytes: &[u8]) -> (Snapshot, Vec<String>) {
    let loaded = OcTree::read(bytes).expect("upstream reads the fixture");
    (
        loaded.tree.to_snapshot().expect("valid tree"),
        loaded.warnings,
    )
}

#[test]
fn every_fixture_reads_as_intended_through_both_readers() {
    for file in fixtures::generate() {
        let bytes = std::fs::read(octomap_fixture(file.name)).expect("read fixture");
        let expected = fixtures::expected_snapshot(file.name);
        let (upstream, warnings) = upstream_snapshot(&bytes);
        assert_eq!(upstream, expected, "{}: upstream library", file.name);
        let native = decode(&bytes, None, ReadLimits::default()).expect("Rust parser reads it");
        let native = Snapshot::from_leaves(native.header.resolution, native.leaves).expect("valid");
        assert_eq!(native, expected, "{}: Rust parser", file.name);
        let read = FormatRegistry::with_default_formats()
            .read_file(&octomap_fixture(file.name), ReadOptions::default())
            .expect("registry reads it");
        assert_eq!(read.map.snapshot, expected, "{}: registry", file.name);
        assert_eq!(read.map.warnings, warnings);
    }
}

#[test]
fn tolerated_header_variants_warn_about_what_they_tolerate() {
    let warnings = |name: &str| upstream_snapshot(&std::fs::read(octomap_fixture(name)).unwrap()).1;
    let size = warnings("size_mismatch.bt");
    assert!(
        size.iter()
            .any(|w| w.contains("size 1") && w.contains("37 nodes")),
        "{size:?}"
    );
    let crlf = warnings("crlf_comments.bt");
    assert_eq!(crlf.len(), 1, "{crlf:?}");
    assert!(crlf[0].contains("mystery"), "{crlf:?}");
    let legacy = warnings("legacy_headerless.bt");
    assert!(
        legacy.iter().any(|w| w.contains("headerless")),
        "{legacy:?}"
    );
    for canonical in [
        "few_voxels.bt",
        "few_voxels.ot",
        "coarse_leaves.bt",
        "coarse_leaves.ot",
        "empty.bt",
    ] {
        assert!(warnings(canonical).is_empty(), "{canonical}");
    }
}

/// convert_octree rewrites a canonical file byte for byte, so the fixtures are exactly what
/// upstream writes. (It refuses `.bt` trees of fewer than two nodes, hence no empty.bt.)
#[test]
fn canonical_fixtures_survive_an_upstream_round_trip() {
    let dir = scratch();
    for name in [
        "few_voxels.bt",
        "few_voxels.ot",
        "coarse_leaves.bt",
        "coarse_leaves.ot",
        "empty.ot",
    ] {
        let input = octomap_fixture(name);
        let output = dir.path().join(name);
        convert_octree(&input, &output);
        assert_eq!(
            std::fs::read(&output).unwrap(),
            std::fs::read(&input).unwrap(),
            "{name}"
        );
    }
}

/// What upstream makes of the tolerated variants: the same tree as the canonical file.
#[test]
fn upstream_normalises_header_variants_to_the_canonical_file() {
    let dir = scratch();
    let canonical = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    for name in ["crlf_comments.bt", "legacy_headerless.bt"] {
        let output = dir.path().join(name);
        convert_octree(&octomap_fixture(name), &output);
        assert_eq!(std::fs::read(&output).unwrap(), canonical, "{name}");
    }
}
