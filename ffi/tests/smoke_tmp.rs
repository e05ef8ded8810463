use froctomap_octomap_ffi::OcTree;
#[test]
fn smoke() {
    let bytes = std::fs::read("/usr/share/doc/liboctomap-dev/examples/data/geb079.bt").unwrap();
    let t0 = std::time::Instant::now();
    let mut loaded = OcTree::read_binary(&bytes).unwrap();
    eprintln!("read {:?} warnings {:?} nodes {} leaves {}", t0.elapsed(), loaded.warnings, loaded.tree.node_count(), loaded.tree.leaf_count());
    let snap = loaded.tree.to_snapshot().unwrap();
    eprintln!("snapshot leaves {} stats {:?}", snap.leaves().len(), snap.stats());
    let rebuilt = OcTree::from_snapshot(&snap).unwrap();
    let ot = rebuilt.write_full().unwrap();
    std::fs::write("/tmp/ours.ot", &ot).unwrap();
    let mut rebuilt2 = OcTree::from_snapshot(&snap).unwrap();
    let bt = rebuilt2.write_binary().unwrap();
    std::fs::write("/tmp/ours.bt", &bt).unwrap();
    assert_eq!(bt, bytes);
    let bt2 = loaded.tree.write_binary().unwrap();
    assert_eq!(bt2, bytes);
}
