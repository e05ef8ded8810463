//! Rewrites `fixtures/octomap/` from `froctomap_test_support::fixtures::generate()`.
//!
//! Run only on purpose (the fixtures are golden files): `cargo run -p froctomap-e2e-tests
//! --example make_fixtures`, then review the diff.
#![allow(clippy::unwrap_used, clippy::expect_used)]

fn main() {
    let dir = froctomap_test_support::fixtures_dir().join("octomap");
    std::fs::create_dir_all(&dir).expect("create fixtures/octomap");
    for file in froctomap_test_support::fixtures::generate() {
        let path = dir.join(file.name);
        std::fs::write(&path, &file.bytes).expect("write fixture");
        println!("{} ({} bytes)", path.display(), file.bytes.len());
    }
}
