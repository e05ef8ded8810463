//! `info`'s summary of a file's dynamics reads classes and models only
//! (`FroctReader::visit_cell_classes`): every cell must read as the full walk's cell does.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use froctomap_convert::*;
use froctomap_file::FroctReader;
use std::path::Path;

/// Per kind (static, rare flips, modelled), the cells of `reader` whose class reads as the
/// full walk's cell; panics on the first that does not.
fn check_every_cell(reader: &FroctReader, what: &str) -> [usize; 3] {
    let model = reader.model();
    let mut kinds = [0; 3];
    for tile in 0..reader.tiles().len() {
        let mut full = Vec::new();
        reader
            .visit_cells(tile, |cell| {
                full.push((
                    cell.start,
                    cell.depth,
                    CellDynamics::of(&cell, model),
                    cell.mask.is_some(),
                ))
            })
            .unwrap();
        let mut classes = Vec::new();
        reader
            .visit_cell_classes(tile, |cell| {
                classes.push((
                    cell.start,
                    cell.depth,
                    CellDynamics::of_class(&cell, model),
                    cell.sometimes_unknown,
                ))
            })
            .unwrap();
        assert_eq!(classes, full, "{what}: tile {tile}");
        for (_, _, dynamics, _) in &full {
            kinds[match dynamics {
                CellDynamics::Static(_) => 0,
                CellDynamics::RareFlips(_) => 1,
                _ => 2,
            }] += 1;
        }
    }
    kinds
}

#[test]
fn cell_classes_read_as_the_full_walk_reads_the_cells() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/froct");
    let mut kinds = [0; 3];
    let mut files = 0;
    for entry in std::fs::read_dir(&fixtures).unwrap() {
        let path = entry.unwrap().path();
        let series = Context::with_default_plugins().open_series(&path).unwrap();
        let reader = match &series {
            FroctFile::Flat(reader) => reader,
            FroctFile::Living(living) => living.base(),
        };
        for (k, n) in check_every_cell(reader, &path.display().to_string())
            .iter()
            .enumerate()
        {
            kinds[k] += n;
        }
        files += 1;
    }
    // The room.
    let dir = tempfile::tempdir().unwrap();
    let context = Context::with_default_plugins();
    let (room, _) = build_room(&context, dir.path(), 48);
    for (k, n) in check_every_cell(&context.open_froct(&room).unwrap(), "room")
        .iter()
        .enumerate()
    {
        kinds[k] += n;
    }
    assert!(files >= 10, "{files} fixtures");
    // Every kind of cell was compared.
    assert!(kinds.iter().all(|&n| n > 0), "{kinds:?}");
}
