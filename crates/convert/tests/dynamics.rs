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

/// The count of `counts` that a cell of `content` adds to.
fn class_of<'a>(counts: &'a mut ClassCounts, content: &froctomap_file::CellContent) -> &'a mut u64 {
    use froctomap_core::Occupancy;
    use froctomap_file::CellContent;
    match content {
        CellContent::Constant(Occupancy::Free) => &mut counts.static_free,
        CellContent::Constant(Occupancy::Occupied) => &mut counts.static_occupied,
        _ => &mut counts.dynamic,
    }
}

/// Cells and voxels by class, counted from the full walk's cells.
fn walked_counts(reader: &FroctReader) -> (ClassCounts, ClassCounts) {
    let (mut cells, mut voxels) = (ClassCounts::default(), ClassCounts::default());
    for tile in 0..reader.tiles().len() {
        reader
            .visit_cells(tile, |cell| {
                let n = froctomap_core::voxels_per_node(cell.depth);
                *class_of(&mut cells, &cell.content) += 1;
                *class_of(&mut voxels, &cell.content) += n;
                if cell.mask.is_some() {
                    cells.unknown_sometimes += 1;
                    voxels.unknown_sometimes += n;
                }
            })
            .unwrap();
    }
    (cells, voxels)
}

/// `info --count` recounts the cells from their classes: the counts of the full walk's
/// cells on every fixture and on a room with static, dynamic and sometimes unknown cells,
/// and there the counts its build wrote in the summary (from the fitted cells).
#[test]
fn recounted_classes_are_the_walked_and_the_built_counts() {
    let context = Context::with_default_plugins();
    let dir = tempfile::tempdir().unwrap();
    let (room, _) = build_room(&context, dir.path(), 48);
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/froct");
    let mut paths = vec![room];
    paths.extend(
        std::fs::read_dir(&fixtures)
            .unwrap()
            .map(|e| e.unwrap().path()),
    );
    for (i, path) in paths.iter().enumerate() {
        let series = context.open_series(path).unwrap();
        let reader = match &series {
            FroctFile::Flat(reader) => reader,
            FroctFile::Living(living) => living.base(),
        };
        let what = path.display();
        let recounted = describe(&context, reader, true).unwrap();
        let (cells, voxels) = walked_counts(reader);
        assert_eq!(
            (recounted.cells, recounted.voxels),
            (cells, voxels),
            "{what}"
        );
        if i == 0 {
            let recorded = describe(&context, reader, false).unwrap();
            assert_eq!(recounted.cells, recorded.cells, "{what}");
            assert_eq!(recounted.voxels, recorded.voxels, "{what}");
            assert!(reader.summary().get("cell_classes").is_some());
            assert!(
                cells.static_free > 0 && cells.dynamic > 0 && cells.unknown_sometimes > 0,
                "{cells:?}"
            );
        }
    }
    assert!(paths.len() >= 10, "{} files", paths.len());
}
