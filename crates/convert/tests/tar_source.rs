//! Adding a source of maps is one module plus one registration: a toy plugin reading maps
//! from a tar archive (entries named by their times, as in a directory of `.bt` files),
//! written by the `tar` crate, builds the same file as the directory it was made from.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

mod common;

use froctomap_convert::{
    build, collect_inputs, observed_map, resolve_observed, BuildOptions, Context, Silent,
    TimeQuery, TimeSource,
};
use froctomap_file::FroctReader;
use std::path::Path;

/// The whole plugin: maps in a tar archive, each entry a map file named by its time.
mod tar_maps {
    use froctomap_convert::time_from_file_name;
    use froctomap_formats::{
        Confidence, PluginError, RecordedMaps, Recording, RecordingFormat, RecordingOptions,
    };
    use std::io::{Read, Seek, SeekFrom};
    use std::path::{Path, PathBuf};
    use std::sync::Arc;

    /// Its descriptor, registered with `register_recording`.
    pub const TAR: RecordingFormat = RecordingFormat {
        name: "tar",
        description: "maps in a tar archive, named by their times",
        extensions: &["tar"],
        // POSIX ustar: the magic at offset 257 of the first header.
        probe: |head| match head.get(257..262) {
            Some(b"ustar") => Confidence::Certain,
            _ => Confidence::No,
        },
        probe_dir: None,
        open,
        open_stream: None,
        create: None,
        create_dir: None,
        describe: None,
    };

    /// Where each map's bytes lie in the archive.
    #[derive(Debug)]
    struct Entries {
        path: PathBuf,
        /// (offset, size) of each map, in time order.
        spans: Vec<(u64, u64)>,
    }

    impl RecordedMaps for Entries {
        fn map_bytes(&self, index: usize, limit: u64) -> Result<Vec<u8>, PluginError> {
            let &(offset, size) = self.spans.get(index).ok_or("no such map")?;
            if size > limit {
                return Err(format!("map {index} has {size} bytes, above {limit}").into());
            }
            let mut file = std::fs::File::open(&self.path)?;
            file.seek(SeekFrom::Start(offset))?;
            let mut bytes = Vec::new();
            file.take(size).read_to_end(&mut bytes)?;
            Ok(bytes)
        }

        fn topic(&self) -> &str {
            "maps"
        }
    }

    fn open(path: &Path, _: &RecordingOptions, _limit: u64) -> Result<Recording, PluginError> {
        let mut archive = tar::Archive::new(std::fs::File::open(path)?);
        let mut found = Vec::new();
        for entry in archive.entries()? {
            let entry = entry?;
            let name = entry.path()?.to_string_lossy().into_owned();
            let time = time_from_file_name(&name).ok_or(format!("{name}: no time in the name"))?;
            found.push((time, (entry.raw_file_position(), entry.size())));
        }
        found.sort_unstable_by_key(|&(time, _)| time);
        let (times, spans) = found.into_iter().unzip();
        let entries = Entries {
            path: path.to_path_buf(),
            spans,
        };
        Ok(Recording::new(times, Vec::new(), Arc::new(entries)))
    }
}

#[test]
fn a_registered_toy_source_builds_what_its_directory_builds() {
    let dir = tempfile::tempdir().unwrap();
    let plain = Context::with_default_plugins();
    let series = dir.path().join("series");
    std::fs::create_dir(&series).unwrap();
    let frames = 12;
    let paths: Vec<_> = (0..frames)
        .map(|i| common::write_frame(&plain, &series, i, &common::frame(i)))
        .collect();
    // The archive, entries in reverse order: the source gives them in time order.
    let archive = dir.path().join("maps.tar");
    let mut builder = tar::Builder::new(std::fs::File::create(&archive).unwrap());
    for path in paths.iter().rev() {
        builder
            .append_path_with_name(path, path.file_name().unwrap())
            .unwrap();
    }
    builder.into_inner().unwrap();

    let mut context = Context::with_default_plugins();
    context
        .formats_mut()
        .register_recording(tar_maps::TAR)
        .unwrap();
    // Registered once.
    assert!(context
        .formats_mut()
        .register_recording(tar_maps::TAR)
        .is_err());

    let from_dir = dir.path().join("dir.froct");
    let from_tar = dir.path().join("tar.froct");
    let inputs = collect_inputs(&plain, &[series], TimeSource::Auto).unwrap();
    build(
        &plain,
        &inputs,
        &from_dir,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    let recorded = collect_inputs(&context, &[archive], TimeSource::Auto).unwrap();
    assert_eq!(recorded.len(), frames as usize);
    assert!(recorded.iter().all(|i| i.is_recorded()));
    let times: Vec<_> = inputs.iter().map(|i| i.time).collect();
    assert_eq!(recorded.iter().map(|i| i.time).collect::<Vec<_>>(), times);
    let report = build(
        &plain,
        &recorded,
        &from_tar,
        &BuildOptions::default(),
        &Silent,
    )
    .unwrap();
    assert_eq!(report.used, frames as usize);

    let maps = |file: &Path| {
        let reader = FroctReader::open(file).unwrap();
        times
            .iter()
            .map(|&t| {
                let when = resolve_observed(&reader, TimeQuery::Instant(t)).unwrap();
                assert!(when.exact);
                observed_map(&reader, when.sample).unwrap()
            })
            .collect::<Vec<_>>()
    };
    let (expected, got) = (maps(&from_dir), maps(&from_tar));
    for (i, (e, g)) in expected.iter().zip(&got).enumerate() {
        assert_eq!(e.leaves(), g.leaves(), "frame {i}");
    }
}
