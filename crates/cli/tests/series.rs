//! The spatio-temporal commands end to end through the binary: build → info → retrieve →
//! predict → export → eval, and their error messages.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_core::{Leaf, Snapshot, VoxelKey};
use froctomap_formats::{FormatRegistry, ReadOptions, WriteOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{err, fails, froctomap, ok, s};

/// A room of 16×16 free voxels with a wall, and a "door" of 4 voxels that is closed
/// (occupied) on frames 2, 3, 6, 7 (every other pair), ten minutes apart.
fn frame(i: u32) -> Snapshot {
    let mut leaves = Vec::new();
    for x in 0..16u16 {
        for y in 0..16u16 {
            let wall = x == 15;
            let door = x == 8 && (4..8).contains(&y);
            let occupied = wall || (door && (i / 2) % 2 == 1);
            leaves.push(Leaf::voxel(
                VoxelKey::new(32768 + x, 32768 + y, 32768),
                if occupied { 3.5 } else { -2.0 },
            ));
        }
    }
    Snapshot::from_leaves(0.1, leaves).unwrap()
}

fn write_series(dir: &Path, n: u32) -> Vec<PathBuf> {
    let registry = FormatRegistry::with_default_formats();
    (0..n)
        .map(|i| {
            let path = dir.join(format!("room_{}.bt", 1_451_865_600 + i * 600));
            registry
                .write_file(&frame(i), &path, WriteOptions::default())
                .unwrap();
            path
        })
        .collect()
}

/// A scratch directory with `n` frames in its `inputs/` subdirectory (so that outputs
/// written beside them are not inputs).
fn series_in_subdir(n: u32) -> (tempfile::TempDir, PathBuf, Vec<PathBuf>) {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("inputs");
    std::fs::create_dir(&inputs).unwrap();
    let files = write_series(&inputs, n);
    (dir, inputs, files)
}

#[test]
fn build_info_retrieve_predict_export_eval() {
    let (dir, inputs, files) = series_in_subdir(8);
    let map = dir.path().join("room.froct");
    build_and_describe(&inputs, &map);
    retrieve_gives_the_inputs_back(dir.path(), &map, &files);
    predict_a_week_later(dir.path(), &map);
    export_and_build_again(dir.path(), &map, &files);
    eval_against_the_inputs(dir.path(), &map, &inputs);
}

/// `build` (text and --json) and `info` (text and --json) of the 8-frame series.
fn build_and_describe(inputs: &Path, map: &Path) {
    let built = ok(&["build", s(inputs), "-o", s(map)]);
    assert!(
        built.contains("snapshots:   8 used of 8 (8 samples, regular axis)"),
        "{built}"
    );
    let report: serde_json::Value = serde_json::from_str(&ok(&[
        "build",
        "--quiet",
        "--json",
        s(inputs),
        "-o",
        s(map),
    ]))
    .unwrap();
    assert_eq!(report["used"], 8);
    assert_eq!(report["cells"]["dynamic"], 4);
    assert!(report["peak_memory_bytes"].as_u64().unwrap() > 0);

    let info = ok(&["info", s(map)]);
    assert!(
        info.contains("2016-01-04T00:00:00Z .. 2016-01-04T01:10:00Z"),
        "{info}"
    );
    assert!(info.contains("8 samples every 600 s"), "{info}");
    assert!(
        info.contains("model:           fremen-periods (lossless)"),
        "{info}"
    );
    let json: serde_json::Value = serde_json::from_str(&ok(&["info", "--json", s(map)])).unwrap();
    assert_eq!(json["voxels"]["dynamic"], 4);
    assert_eq!(json["input_files"], 8);
}

/// `retrieve` of stored snapshots gives the inputs back; between them, the one before.
fn retrieve_gives_the_inputs_back(dir: &Path, map: &Path, files: &[PathBuf]) {
    // Retrieve by ISO time, by Unix seconds and by index: identical to the input file.
    for (i, time) in [
        (2usize, "2016-01-04T00:20:00Z"),
        (3, "1451867400"),
        (5, "index:5"),
    ] {
        let out = dir.join(format!("r{i}.bt"));
        ok(&["retrieve", s(map), "--time", time, "-o", s(&out)]);
        assert_eq!(
            std::fs::read(&out).unwrap(),
            std::fs::read(&files[i]).unwrap(),
            "{time}"
        );
    }
    // Between snapshots: the last earlier one, with a note.
    let between = froctomap(&[
        "retrieve",
        s(map),
        "--time",
        "2016-01-04T00:25:00Z",
        "-o",
        s(&dir.join("b.bt")),
    ]);
    assert!(String::from_utf8_lossy(&between.stderr)
        .contains("using the last one before it, at 2016-01-04T00:20:00Z"));
}

/// `predict` beyond the series, with a note.
fn predict_a_week_later(dir: &Path, map: &Path) {
    // Predict a week later as .ot and .bt.
    let ot = dir.join("later.ot");
    let note = froctomap(&[
        "predict",
        s(map),
        "--time",
        "2016-01-11T00:00:00Z",
        "-o",
        s(&ot),
    ]);
    assert!(note.status.success());
    assert!(String::from_utf8_lossy(&note.stderr).contains("days after the last snapshot"));
    let predicted = FormatRegistry::with_default_formats()
        .read_file(&ot, ReadOptions::default())
        .unwrap();
    assert_eq!(predicted.map.snapshot.voxels().count(), 256);
}

/// `export` writes maps and a manifest that `build` reads again.
fn export_and_build_again(dir: &Path, map: &Path, files: &[PathBuf]) {
    // Export retrieved maps every 20 minutes: files + manifest that build reads again.
    let exported = dir.join("exported");
    ok(&[
        "export",
        s(map),
        "--from",
        "2016-01-04T00:00:00Z",
        "--to",
        "2016-01-04T01:10:00Z",
        "--every",
        "20min",
        "--mode",
        "retrieve",
        "-o",
        s(&exported),
    ]);
    let manifest = std::fs::read_to_string(exported.join("manifest.csv")).unwrap();
    assert_eq!(manifest.lines().count(), 1 + 4, "{manifest}");
    assert_eq!(
        std::fs::read(exported.join("map_20160104T002000Z.bt")).unwrap(),
        std::fs::read(&files[2]).unwrap()
    );
    ok(&[
        "build",
        "--quiet",
        s(&exported.join("manifest.csv")),
        "-o",
        s(&dir.join("again.froct")),
    ]);
}

/// `eval` against the inputs: JSON, table and reliability picture.
fn eval_against_the_inputs(dir: &Path, map: &Path, inputs: &Path) {
    // Evaluation against the inputs: stored states exact.
    let eval: serde_json::Value = serde_json::from_str(&ok(&[
        "eval",
        "--quiet",
        "--json",
        s(map),
        "--against",
        s(inputs),
    ]))
    .unwrap();
    assert_eq!(eval["inside"], 8);
    let stored = eval["reconstruction"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r[0] == "stored")
        .unwrap();
    assert_eq!(stored[1]["all"]["wrong"], 0);
    // Exact 0/1 states: no squared error, and −ln(1 − ε) of log loss per voxel.
    assert_eq!(stored[1]["dynamic"]["brier"], 0.0);
    let epsilon = eval["log_loss_epsilon"].as_f64().unwrap();
    let loss = stored[1]["dynamic"]["log_loss"].as_f64().unwrap();
    assert!((loss + (1.0 - epsilon).ln()).abs() < 1e-9, "{loss}");
    let png = dir.join("reliability.png");
    let table = ok(&[
        "eval",
        "--quiet",
        s(map),
        "--against",
        s(inputs),
        "--png",
        s(&png),
    ]);
    assert!(
        table.contains("| method | all voxels | non-empty | dynamic |"),
        "{table}"
    );
    assert!(
        table.contains("| method | Brier / log loss, all |"),
        "{table}"
    );
    assert!(
        table.contains("calibration, reconstruction, dynamic voxels"),
        "{table}"
    );
    let picture = image::open(&png).unwrap();
    assert!(picture.width() > 100 && picture.height() > 100);
    // --stride 3 compares the 1st, 4th and 7th maps: the same report as those three alone.
    let strided = dir.join("every-third");
    std::fs::create_dir(&strided).unwrap();
    let mut names: Vec<_> = std::fs::read_dir(inputs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "bt"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 8);
    for name in names.iter().step_by(3) {
        std::fs::copy(name, strided.join(name.file_name().unwrap())).unwrap();
    }
    let eval_of = |args: &[&str]| -> serde_json::Value {
        let mut all = vec!["eval", "--quiet", "--json", s(map)];
        all.extend_from_slice(args);
        serde_json::from_str(&ok(&all)).unwrap()
    };
    let every_third = eval_of(&["--stride", "3", "--against", s(inputs)]);
    assert_eq!(every_third["inside"], 3);
    assert_eq!(every_third, eval_of(&["--against", s(&strided)]));
    assert_ne!(every_third, eval);
    let refused = fails(&["eval", s(map), "--against", s(inputs), "--stride", "0"]);
    assert!(refused.contains("--stride"), "{refused}");
}

/// Every toggle layout (whole lists = format 1.0, blocks of 3 samples in 1.1 and 1.2, the
/// default) gives back every input exactly, through the tiled native `.bt` writer and
/// through the C++ library's writer alike.
#[test]
fn every_toggle_layout_retrieves_every_snapshot_exactly() {
    let (dir, inputs, files) = series_in_subdir(8);
    for (block, format, version) in [
        ("0", "1.2", "FROctomap 1.0"),
        ("3", "1.1", "FROctomap 1.1"),
        ("3", "1.2", "FROctomap 1.2"),
        ("256", "1.2", "FROctomap 1.2"),
    ] {
        let map = dir.path().join(format!("blocks-{block}-{format}.froct"));
        ok(&[
            "build",
            "--quiet",
            "--toggle-block",
            block,
            "--format-version",
            format,
            s(&inputs),
            "-o",
            s(&map),
        ]);
        let info = ok(&["info", s(&map)]);
        assert!(info.contains(version), "{block}: {info}");
        for (i, file) in files.iter().enumerate() {
            let index = format!("index:{i}");
            for backend in ["native", "octomap"] {
                let out = dir
                    .path()
                    .join(format!("r-{block}-{format}-{i}-{backend}.bt"));
                ok(&[
                    "--backend",
                    backend,
                    "retrieve",
                    s(&map),
                    "--time",
                    &index,
                    "-o",
                    s(&out),
                ]);
                assert_eq!(
                    std::fs::read(&out).unwrap(),
                    std::fs::read(file).unwrap(),
                    "blocks of {block}, sample {i}, {backend} writer"
                );
            }
        }
    }
}

/// Every registered model builds a lossless file that retrieves every input exactly; model
/// options are checked against the chosen model.
#[test]
fn models_come_from_the_registry() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("inputs");
    std::fs::create_dir(&inputs).unwrap();
    let files = write_series(&inputs, 8);
    let help = ok(&["build", "--help"]);
    for model in ["static", "fremen-regular", "fremen-periods", "markov"] {
        assert!(help.contains(&format!("{model}: ")), "{help}");
        let map = dir.path().join(format!("{model}.froct"));
        ok(&[
            "build",
            "--quiet",
            "--model",
            model,
            s(&inputs),
            "-o",
            s(&map),
        ]);
        assert!(ok(&["info", s(&map)]).contains(&format!("model:           {model} (lossless)")));
        for (i, file) in files.iter().enumerate() {
            let out = dir.path().join(format!("{model}-{i}.bt"));
            let index = format!("index:{i}");
            ok(&["retrieve", s(&map), "--time", &index, "-o", s(&out)]);
            assert_eq!(
                std::fs::read(&out).unwrap(),
                std::fs::read(file).unwrap(),
                "{model} {i}"
            );
        }
    }
    let map = dir.path().join("options.froct");
    let build = |extra: &[&str]| {
        let mut args = vec!["build", "--quiet", s(&inputs), "-o", s(&map)];
        args.extend_from_slice(extra);
        args.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |args: Vec<String>| froctomap(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        run(build(&["--model-option", "order=2", "--criterion", "size"]))
            .status
            .success()
    );
    let e = run(build(&["--model", "markov", "--order", "3"]));
    assert!(
        String::from_utf8_lossy(&e.stderr).contains("--order: model markov has no option order")
    );
    let e = run(build(&["--model-option", "colour=red"]));
    assert!(String::from_utf8_lossy(&e.stderr).contains("has no option \"colour\""));
    let e = run(build(&["--model", "hmm"]));
    assert!(String::from_utf8_lossy(&e.stderr)
        .contains("registered: static, fremen-regular, fremen-periods, markov"));
}

#[test]
fn errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_series(dir.path(), 3);
    let map = dir.path().join("room.froct");
    // Duplicate time through a manifest.
    std::fs::write(
        dir.path().join("dup.csv"),
        format!("{},1451865600\n{},1451865600\n", s(&files[0]), s(&files[1])),
    )
    .unwrap();
    let e = err(&["build", s(&dir.path().join("dup.csv")), "-o", s(&map)]);
    assert!(e.contains("same time 2016-01-04T00:00:00Z"), "{e}");
    // Unwritable output.
    let e = err(&["build", s(dir.path()), "-o", "/nonexistent-dir/x.froct"]);
    assert!(e.contains("/nonexistent-dir/x.froct"), "{e}");
    ok(&["build", "--quiet", s(dir.path()), "-o", s(&map)]);
    // Time outside any sensible range, and before the series.
    let e = err(&[
        "retrieve",
        s(&map),
        "--time",
        "99999999999",
        "-o",
        s(&dir.path().join("x.bt")),
    ]);
    assert!(e.contains("outside the supported range"), "{e}");
    let e = err(&[
        "retrieve",
        s(&map),
        "--time",
        "2010-01-01",
        "-o",
        s(&dir.path().join("x.bt")),
    ]);
    assert!(e.contains("before the first snapshot"), "{e}");
    assert!(!dir.path().join("x.bt").exists());
    // Not a FROctomap file.
    let e = err(&[
        "retrieve",
        s(&files[0]),
        "--time",
        "index:0",
        "-o",
        s(&dir.path().join("x.bt")),
    ]);
    assert!(e.contains("not a FROctomap series file"), "{e}");
    // Output formats are the registry's writable ones, listed when another is given.
    let out = froctomap(&[
        "retrieve",
        s(&map),
        "--time",
        "index:0",
        "--format",
        "png",
        "-o",
        s(&dir.path().join("x.png")),
    ]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("png"), "{e}");
    assert!(e.contains("[possible values: bt, ot]"), "{e}");
    // Too many maps: the limit, and the option that gets past it.
    let e = err(&[
        "export",
        s(&map),
        "--from",
        "2016-01-04",
        "--to",
        "2016-02-04",
        "--every",
        "1",
        "-o",
        s(&dir.path().join("many")),
    ]);
    assert!(
        e.contains("more than the limit") && e.contains("--every"),
        "{e}"
    );
    // A broken input names the file; the CLI adds the option that leaves it out.
    let bytes = std::fs::read(&files[1]).unwrap();
    std::fs::write(&files[1], &bytes[..bytes.len() / 2]).unwrap();
    let e = err(&["build", s(dir.path()), "-o", s(&dir.path().join("b.froct"))]);
    assert!(
        e.contains(s(&files[1])) && e.contains("hint: use --skip-bad"),
        "{e}"
    );
    // A damaged FROctomap file.
    let mut bytes = std::fs::read(&map).unwrap();
    let n = bytes.len();
    bytes.truncate(n - 5);
    std::fs::write(&map, &bytes).unwrap();
    let e = err(&["info", s(&map)]);
    assert!(e.contains("room.froct") && e.contains("end magic"), "{e}");
}

#[test]
fn outputs_never_replace_their_inputs() {
    let (dir, inputs, files) = series_in_subdir(3);
    let first = std::fs::read(&files[0]).unwrap();
    let destroys = |args: &[&str]| {
        let e = err(args);
        assert!(e.contains("would destroy the input"), "{args:?}: {e}");
    };
    destroys(&["build", s(&files[0]), s(&files[1]), "-o", s(&files[0])]);
    destroys(&["convert", s(&files[0]), s(&files[0])]);
    // The same file through a symbolic and a hard link.
    let soft = dir.path().join("soft.bt");
    std::os::unix::fs::symlink(&files[0], &soft).unwrap();
    destroys(&["build", s(&inputs), "-o", s(&soft)]);
    let hard = dir.path().join("hard.bt");
    std::fs::hard_link(&files[1], &hard).unwrap();
    destroys(&["convert", s(&files[1]), s(&hard)]);
    assert_eq!(std::fs::read(&files[0]).unwrap(), first);

    let map = dir.path().join("room.froct");
    ok(&["build", "--quiet", s(&inputs), "-o", s(&map)]);
    let archive = std::fs::read(&map).unwrap();
    let map_link = dir.path().join("room-link.froct");
    std::fs::hard_link(&map, &map_link).unwrap();
    for output in [&map, &map_link] {
        destroys(&[
            "retrieve",
            s(&map),
            "--time",
            "index:0",
            "--format",
            "bt",
            "-o",
            s(output),
        ]);
        destroys(&[
            "predict",
            s(&map),
            "--time",
            "index:0",
            "--format",
            "bt",
            "-o",
            s(output),
        ]);
    }
    assert_eq!(std::fs::read(&map).unwrap(), archive);

    // An export goes into a new or empty directory unless told to overwrite.
    let export = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "export",
            s(&map),
            "--from",
            "1451865600",
            "--to",
            "1451866800",
            "--every",
            "10min",
            "-o",
            s(out),
        ];
        args.extend_from_slice(extra);
        args.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |args: Vec<String>| froctomap(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let refused = run(export(&inputs, &[]));
    assert_eq!(refused.status.code(), Some(1));
    let e = String::from_utf8(refused.stderr).unwrap();
    assert!(e.contains("not empty") && e.contains("--overwrite"), "{e}");
    assert!(!inputs.join("manifest.csv").exists());
    assert!(run(export(&inputs, &["--overwrite"])).status.success());
    assert!(inputs.join("manifest.csv").exists());
    assert!(run(export(&dir.path().join("new"), &[])).status.success());
}

#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_series(dir.path(), 1);
    let mut child = Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args(["info", s(&files[0])])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before the first line is written (`froctomap info x | head -0`).
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert_eq!(stderr, "");
}

#[test]
fn each_error_is_said_once_and_map_files_are_not_series() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_series(dir.path(), 2);
    let missing = dir.path().join("missing.froct");
    let e = err(&["info", s(&missing)]);
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    let map = dir.path().join("room.froct");
    ok(&["build", "--quiet", s(dir.path()), "-o", s(&map)]);
    let truncated = dir.path().join("truncated.froct");
    let bytes = std::fs::read(&map).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let e = err(&["info", s(&truncated)]);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert_eq!(e.matches("corrupt").count(), 1, "{e}");

    let out = dir.path().join("x.bt");
    let out = s(&out);
    for args in [
        vec!["retrieve", s(&files[0]), "--time", "index:0", "-o", out],
        vec!["predict", s(&files[0]), "--time", "0", "-o", out],
        vec![
            "export",
            s(&files[0]),
            "--from",
            "0",
            "--to",
            "0",
            "--every",
            "1",
            "-o",
            out,
        ],
    ] {
        let e = err(&args);
        assert!(
            e.contains("this is a map file (format `bt`)"),
            "{args:?}: {e}"
        );
        assert!(e.contains("build a .froct from it first"), "{e}");
    }
}

#[test]
fn completions_and_manual_page_come_from_the_command_line() {
    let bash = ok(&["completions", "bash"]);
    assert!(bash.contains("_froctomap()"), "{bash}");
    assert!(bash.contains("retrieve") && bash.contains("--toggle-block"));
    let zsh = ok(&["completions", "zsh"]);
    assert!(zsh.starts_with("#compdef froctomap"), "{zsh}");
    // An unknown shell is a usage error (clap's status 2) naming the known ones.
    let unknown = froctomap(&["completions", "tcsh"]);
    assert_eq!(unknown.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("zsh"));
    let page = ok(&["man"]);
    assert!(page.contains(".TH froctomap 1"), "{page}");
    assert!(page.contains("retrieve") && page.contains("completions"));
}

#[test]
fn a_fixed_creation_time_makes_builds_reproducible() {
    let (dir, inputs, _) = series_in_subdir(3);
    let build = |name: &str, created: Option<&str>, epoch: Option<&str>| {
        let out = dir.path().join(name);
        let mut command = Command::new(env!("CARGO_BIN_EXE_froctomap"));
        command.args(["build", "--quiet", s(&inputs), "-o", s(&out)]);
        if let Some(time) = created {
            command.args(["--created", time]);
        }
        command.env_remove("SOURCE_DATE_EPOCH");
        if let Some(epoch) = epoch {
            command.env("SOURCE_DATE_EPOCH", epoch);
        }
        let run = command.output().unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let info = ok(&["info", "--json", s(&out)]);
        (std::fs::read(&out).unwrap(), info)
    };
    let (flag, info) = build("a.froct", Some("2020-01-01T00:00:00Z"), None);
    assert!(info.contains("2020-01-01T00:00:00Z"), "{info}");
    let (epoch, _) = build("b.froct", None, Some("1577836800"));
    assert_eq!(flag, epoch);
    // The flag wins over the environment.
    let (both, _) = build("c.froct", Some("1577836800"), Some("1"));
    assert_eq!(flag, both);
    let e = {
        let out = Command::new(env!("CARGO_BIN_EXE_froctomap"))
            .args(["build", s(&inputs), "-o", s(&dir.path().join("d.froct"))])
            .env("SOURCE_DATE_EPOCH", "yesterday")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1));
        String::from_utf8(out.stderr).unwrap()
    };
    assert!(e.contains("SOURCE_DATE_EPOCH"), "{e}");
}

#[test]
fn names_and_metadata_from_files_cannot_drive_the_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_series(dir.path(), 3);
    // A snapshot whose name carries an escape sequence and a forged line.
    let hostile = dir.path().join("room\u{1b}[2J\nerror: forged.bt");
    std::fs::copy(&files[0], &hostile).unwrap();
    let info = ok(&["info", s(&hostile)]);
    assert!(!info.contains('\u{1b}'), "{info}");
    assert!(info.contains("room\\u{1b}[2J\\nerror: forged.bt"), "{info}");
    let e = err(&["retrieve", s(&hostile), "--time", "0", "-o", "x.bt"]);
    assert!(!e.contains('\u{1b}') && e.lines().count() == 1, "{e}");

    // A file whose metadata was written by someone else's tool.
    let context = froctomap_convert::Context::with_default_plugins();
    let inputs =
        froctomap_convert::collect_inputs(&context, &files, froctomap_convert::TimeSource::Auto)
            .unwrap();
    let mut options = froctomap_convert::BuildOptions::default();
    options.metadata.insert(
        "creator".into(),
        serde_json::Value::from("evil\u{1b}]0;title\u{7}\nfile: forged"),
    );
    let map = dir.path().join("room.froct");
    froctomap_convert::build(
        &context,
        &inputs,
        &map,
        &options,
        &froctomap_convert::Silent,
    )
    .unwrap();
    let info = ok(&["info", s(&map)]);
    assert!(
        !info.contains('\u{1b}') && !info.contains('\u{7}'),
        "{info}"
    );
    let file_lines = info.lines().filter(|l| l.starts_with("file:")).count();
    assert_eq!(file_lines, 1, "{info}");
    assert!(
        info.contains("by evil\\u{1b}]0;title\\u{7}\\nfile: forged"),
        "{info}"
    );
}

#[test]
fn fifos_are_refused_before_opening_and_link_loops_end() {
    let dir = tempfile::tempdir().unwrap();
    let files = write_series(dir.path(), 2);
    let fifo = dir.path().join("room_1451866800.bt");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let manifest_fifo = dir.path().join("list.csv");
    assert!(Command::new("mkfifo")
        .arg(&manifest_fifo)
        .status()
        .unwrap()
        .success());
    let manifest = dir.path().join("rows.csv");
    std::fs::write(
        &manifest,
        format!("{},1451865600\n{},1451866800\n", s(&files[0]), s(&fifo)),
    )
    .unwrap();
    let out = dir.path().join("x.froct");
    // Each of these would wait forever on the FIFO if it were opened.
    for args in [
        vec!["info", s(&fifo)],
        vec!["convert", s(&fifo), "x.ot"],
        vec!["build", s(&fifo), s(&files[0]), "-o", s(&out)],
        vec!["build", s(&manifest), "-o", s(&out)],
        vec!["build", s(&manifest_fifo), "-o", s(&out)],
        vec!["retrieve", s(&fifo), "--time", "0", "-o", "x.bt"],
    ] {
        let e = err(&args);
        assert!(e.contains("a FIFO, not a regular file"), "{args:?}: {e}");
    }
    // Listing a directory takes its regular files only, as a plain glob does.
    ok(&["build", "--quiet", s(dir.path()), "-o", s(&out)]);
    std::fs::remove_file(&fifo).unwrap();

    // `**` over two links to an ancestor: ends, with each real file once.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    std::os::unix::fs::symlink("..", sub.join("up")).unwrap();
    std::os::unix::fs::symlink("../sub", sub.join("again")).unwrap();
    std::fs::copy(&files[1], sub.join("room_1451866800.bt")).unwrap();
    let pattern = format!("{}/**/*.bt", dir.path().display());
    ok(&["build", "--quiet", &pattern, "-o", s(&out)]);
    let info = ok(&["info", "--json", s(&out)]);
    assert!(info.contains("\"samples\": 3"), "{info}");
}

#[test]
fn dry_run_lists_times_and_their_sources_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let registry = FormatRegistry::with_default_formats();
    for (i, name) in ["2024-03-01-10-15-00.bt", "2024-03-01_10-25-00.bt"]
        .iter()
        .enumerate()
    {
        registry
            .write_file(
                &frame(i as u32),
                &dir.path().join(name),
                WriteOptions::default(),
            )
            .unwrap();
    }
    let out = ok(&["build", s(dir.path()), "--dry-run"]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert!(
        lines[0].starts_with("2024-03-01T10:15:00Z  file name"),
        "{out}"
    );
    assert!(
        lines[1].starts_with("2024-03-01T10:25:00Z  file name"),
        "{out}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);

    // Numbered files: natural order under --start/--step, refused without.
    let numbered = tempfile::tempdir().unwrap();
    for i in [1u32, 2, 10, 12] {
        registry
            .write_file(
                &frame(i),
                &numbered.path().join(format!("map_{i}.bt")),
                WriteOptions::default(),
            )
            .unwrap();
    }
    let out = ok(&[
        "build",
        s(numbered.path()),
        "--start",
        "2024-03-01T00:00:00Z",
        "--step",
        "1min",
        "--dry-run",
    ]);
    let order: Vec<&str> = out.lines().map(|l| l.rsplit('/').next().unwrap()).collect();
    assert_eq!(
        order,
        ["map_1.bt", "map_2.bt", "map_10.bt", "map_12.bt"],
        "{out}"
    );
    assert!(
        out.lines()
            .nth(3)
            .unwrap()
            .starts_with("2024-03-01T00:03:00Z  start + step"),
        "{out}"
    );
    let padded = tempfile::tempdir().unwrap();
    registry
        .write_file(
            &frame(0),
            &padded.path().join("map_0000000041.bt"),
            WriteOptions::default(),
        )
        .unwrap();
    let message = err(&["build", s(padded.path()), "--dry-run"]);
    assert!(
        message.contains("before 1990") && message.contains("--start"),
        "{message}"
    );
}

#[test]
fn zoneless_times_are_utc_said_once_or_read_in_tz() {
    let dir = tempfile::tempdir().unwrap();
    let registry = FormatRegistry::with_default_formats();
    for name in ["2024-03-01-10-15-00.bt", "2024-03-01-10-25-00.bt"] {
        registry
            .write_file(&frame(0), &dir.path().join(name), WriteOptions::default())
            .unwrap();
    }
    let notice = "times without a zone are read as UTC";
    let out = froctomap(&["build", s(dir.path()), "--dry-run"]);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.matches(notice).count(), 1, "{stderr}");
    let quiet = froctomap(&["build", s(dir.path()), "--dry-run", "-q"]);
    assert!(quiet.stderr.is_empty());
    let shifted = froctomap(&["build", s(dir.path()), "--dry-run", "--tz", "+01:00"]);
    assert!(!String::from_utf8_lossy(&shifted.stderr).contains(notice));
    let shifted = String::from_utf8(shifted.stdout).unwrap();
    assert!(shifted.starts_with("2024-03-01T09:15:00Z"), "{shifted}");
    let bad = froctomap(&["build", s(dir.path()), "--dry-run", "--tz", "Mars/Olympus"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not a time zone"));

    // Times on the command line: one notice, and none for Unix seconds or with --tz.
    let out = dir.path().join("s.froct");
    ok(&["build", s(dir.path()), "-o", s(&out), "-q"]);
    let at = dir.path().join("at.bt");
    let run = froctomap(&[
        "retrieve",
        s(&out),
        "--time",
        "2024-03-01T10:20:00",
        "-o",
        s(&at),
    ]);
    assert_eq!(
        String::from_utf8_lossy(&run.stderr).matches(notice).count(),
        1
    );
    let run = froctomap(&["retrieve", s(&out), "--time", "1709288400", "-o", s(&at)]);
    assert!(!String::from_utf8_lossy(&run.stderr).contains(notice));
    // 11:20 at +01:00 is 10:20Z: the first snapshot (10:15) is the last one before it.
    let run = froctomap(&[
        "retrieve",
        s(&out),
        "--time",
        "2024-03-01T11:20:00",
        "--tz",
        "+01:00",
        "-o",
        s(&at),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("at 2024-03-01T10:15:00Z"), "{stderr}");
}

#[test]
fn times_files_and_manifests_that_leave_files_out() {
    let dir = tempfile::tempdir().unwrap();
    let registry = FormatRegistry::with_default_formats();
    for i in [1u32, 2, 10] {
        registry
            .write_file(
                &frame(i),
                &dir.path().join(format!("map_{i}.bt")),
                WriteOptions::default(),
            )
            .unwrap();
    }
    let stamps = dir.path().join("stamps.txt");
    std::fs::write(&stamps, "1700000000\n1700000060\n1700000120\n").unwrap();
    let out = ok(&[
        "build",
        s(dir.path()),
        "--times-file",
        s(&stamps),
        "--dry-run",
    ]);
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[2].starts_with("2023-11-14T22:15:20Z  times file") && lines[2].ends_with("map_10.bt"),
        "{out}"
    );

    std::fs::write(
        dir.path().join("manifest.csv"),
        "file,stamp\nmap_1.bt,1700000000\n",
    )
    .unwrap();
    let run = froctomap(&["build", s(dir.path()), "--dry-run"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("warning:") && stderr.contains("does not list 2 map file(s)"),
        "{stderr}"
    );
    assert_eq!(String::from_utf8_lossy(&run.stdout).lines().count(), 1);
}

#[test]
fn retrieve_nearest_last_and_out_of_span_say_what_they_do() {
    let (dir, inputs, _files) = series_in_subdir(8);
    let froct = dir.path().join("s.froct");
    ok(&["build", s(&inputs), "-o", s(&froct), "-q"]);
    let at = dir.path().join("at.bt");
    let retrieve = |extra: &[&str]| {
        let mut args = vec!["retrieve", s(&froct), "-o", s(&at)];
        args.extend_from_slice(extra);
        let out = froctomap(&args);
        (out.status.code(), String::from_utf8(out.stderr).unwrap())
    };
    // 16 min after the first snapshot: the 10-min one before it, or the 20-min one nearest.
    let (_, before) = retrieve(&["--time", "1451866560"]);
    assert!(
        before.contains("last one before it, at 2016-01-04T00:10:00Z"),
        "{before}"
    );
    let (_, nearest) = retrieve(&["--time", "1451866560", "--nearest"]);
    assert!(
        nearest.contains("nearest one, at 2016-01-04T00:20:00Z"),
        "{nearest}"
    );
    assert!(nearest.contains("(sample 2)"), "{nearest}");
    // A year later: the last snapshot, said loudly.
    let (code, late) = retrieve(&["--time", "2017-01-04T00:00:00Z"]);
    assert_eq!(code, Some(0));
    assert!(
        late.contains("warning: 2017-01-04T00:00:00Z is outside the file's span"),
        "{late}"
    );
    assert!(late.contains("the last snapshot as observed"), "{late}");
    // Before the first with --nearest: the first, with the same warning.
    let (code, early) = retrieve(&["--time", "2015-01-04T00:00:00Z", "--nearest"]);
    assert_eq!(code, Some(0), "{early}");
    assert!(
        early.contains("the first snapshot as observed") && early.contains("(sample 0)"),
        "{early}"
    );
    for last in ["last", "index:-1"] {
        let (_, said) = retrieve(&["--time", last]);
        assert!(
            said.contains("observed at 2016-01-04T01:10:00Z (sample 7)"),
            "{said}"
        );
    }
    let (code, beyond) = retrieve(&["--time", "index:8"]);
    assert_eq!(code, Some(1));
    assert!(
        beyond.contains("valid: index:0 .. index:7, or index:-1 .. index:-8"),
        "{beyond}"
    );
    let (_, before_start) = retrieve(&["--time", "index:-9"]);
    assert!(
        before_start.contains("valid: index:-1 .. index:-8"),
        "{before_start}"
    );
    let (_, zero) = retrieve(&["--time", "index:-0"]);
    assert!(zero.contains("`last` the last"), "{zero}");

    // Export of retrievals: each snapshot once, at its own time.
    let out = dir.path().join("out");
    ok(&[
        "export",
        s(&froct),
        "--mode",
        "retrieve",
        "--from",
        "1451865600",
        "--to",
        "1451869800",
        "--every",
        "5min",
        "-o",
        s(&out),
        "-q",
    ]);
    let manifest = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
    let times: Vec<&str> = manifest
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap())
        .collect();
    let expected: Vec<String> = (0..8)
        .map(|i| (1_451_865_600 + i * 600).to_string())
        .collect();
    assert_eq!(times, expected, "{manifest}");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 9);
}

/// Issue 16 item 13: a stray file of another resolution sorted first used to set the
/// series' resolution, so that `--skip-bad` kept it alone and succeeded.
#[test]
fn skip_bad_keeps_the_resolution_most_inputs_have() {
    let (dir, inputs, files) = series_in_subdir(5);
    // Sorted (and timed) before the others.
    let stray = inputs.join(format!("room_{}.bt", 1_451_865_600 - 600));
    let coarse = Snapshot::from_leaves(0.2, frame(0).leaves().to_vec()).unwrap();
    FormatRegistry::with_default_formats()
        .write_file(&coarse, &stray, WriteOptions::default())
        .unwrap();
    let map = dir.path().join("room.froct");
    let out = froctomap(&["build", "--skip-bad", s(&inputs), "-o", s(&map)]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{e}");
    assert!(e.contains(s(&stray)), "the stray file is listed: {e}");
    let info = ok(&["info", "--json", s(&map)]);
    assert!(info.contains("\"resolution_m\": 0.1"), "{info}");
    // The user's resolution decides; leaving 5 of 6 out needs saying so, and every file
    // left out is named in one run.
    let e = err(&[
        "build",
        "--skip-bad",
        "--resolution",
        "0.2",
        s(&inputs),
        "-o",
        s(&map),
    ]);
    assert!(e.contains("5 of 6 inputs would be left out"), "{e}");
    assert!(files.iter().all(|f| e.contains(s(f))), "{e}");
    assert!(e.contains("--allow-mostly-skipped"), "{e}");
    ok(&[
        "build",
        "--quiet",
        "--skip-bad",
        "--allow-mostly-skipped",
        "--resolution",
        "0.2",
        s(&inputs),
        "-o",
        s(&map),
    ]);
    let info = ok(&["info", "--json", s(&map)]);
    assert!(info.contains("\"resolution_m\": 0.2"), "{info}");
}

/// `append --skip-bad` refuses to go on when most new inputs are left out, and the hint's
/// `--allow-mostly-skipped` exists on `append` too.
#[test]
fn append_refuses_mostly_skipped_inputs_unless_allowed() {
    let (dir, inputs, _) = series_in_subdir(4);
    let map = dir.path().join("room.froct");
    ok(&["build", "--quiet", s(&inputs), "-o", s(&map)]);
    let later = dir.path().join("later");
    std::fs::create_dir(&later).unwrap();
    let registry = FormatRegistry::with_default_formats();
    let good = later.join(format!("room_{}.bt", 1_451_865_600 + 4 * 600));
    registry
        .write_file(&frame(4), &good, WriteOptions::default())
        .unwrap();
    for i in 5..8 {
        let bad = later.join(format!("room_{}.bt", 1_451_865_600 + i * 600));
        std::fs::write(&bad, b"not an octree").unwrap();
    }
    let before = std::fs::read(&map).unwrap();
    let e = err(&["append", "--skip-bad", s(&map), s(&later)]);
    assert!(e.contains("3 of 4 inputs would be left out"), "{e}");
    assert!(e.contains("--allow-mostly-skipped"), "{e}");
    assert_eq!(
        std::fs::read(&map).unwrap(),
        before,
        "a refused append leaves the file"
    );
    ok(&[
        "append",
        "--quiet",
        "--skip-bad",
        "--allow-mostly-skipped",
        s(&map),
        s(&later),
    ]);
    // The good map joins; the three left out are missing samples on the axis.
    let info = ok(&["info", "--json", s(&map)]);
    assert!(info.contains("\"samples\": 8"), "{info}");
    assert!(info.contains("\"missing\": 3"), "{info}");
}

/// Makes `files` really bad inputs, one of each kind a directory of map files can hold,
/// and gives the code `--skip-bad`'s report must give each (issue 31: a typed reason).
fn spoil(files: &[PathBuf]) -> Vec<(PathBuf, &'static str)> {
    let cut = std::fs::read(&files[0]).unwrap();
    std::fs::write(&files[0], &cut[..cut.len() - 7]).unwrap();
    std::fs::write(&files[1], b"timestamp,x,y,z\n1,2,3,4\n").unwrap();
    std::fs::write(&files[2], b"").unwrap();
    let coarse = Snapshot::from_leaves(0.2, frame(0).leaves().to_vec()).unwrap();
    FormatRegistry::with_default_formats()
        .write_file(&coarse, &files[3], WriteOptions::default())
        .unwrap();
    let codes = ["malformed", "not-a-map", "empty", "resolution-mismatch"];
    files.iter().cloned().zip(codes).collect()
}

/// The `skipped` of a `--json` report as (path, code), checking each entry is an object of
/// exactly `path`, `code` and a non-empty `message`.
fn skipped_codes(report: &serde_json::Value) -> Vec<(PathBuf, String)> {
    let listed = report["skipped"].as_array().expect("skipped is a list");
    listed
        .iter()
        .map(|entry| {
            let fields = entry.as_object().expect("each skipped input is an object");
            let mut keys: Vec<&str> = fields.keys().map(String::as_str).collect();
            keys.sort_unstable();
            assert_eq!(keys, ["code", "message", "path"], "{entry}");
            assert!(!entry["message"].as_str().unwrap().is_empty(), "{entry}");
            (
                PathBuf::from(entry["path"].as_str().unwrap()),
                entry["code"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

/// Each input `build --skip-bad --json` and `append --skip-bad --json` leave out is listed
/// as `{"path", "code", "message"}`, its code saying why: a truncated .bt, a file that is no
/// map, an empty file, a map of another resolution.
#[test]
fn skipped_inputs_carry_their_reason_code_in_json() {
    let (dir, inputs, files) = series_in_subdir(9);
    let mut expected = spoil(&files[1..5]);
    expected.sort();
    let map = dir.path().join("room.froct");
    let report: serde_json::Value = serde_json::from_str(&ok(&[
        "build",
        "--quiet",
        "--json",
        "--skip-bad",
        s(&inputs),
        "-o",
        s(&map),
    ]))
    .unwrap();
    let mut listed = skipped_codes(&report);
    listed.sort();
    let expected: Vec<(PathBuf, String)> = expected
        .into_iter()
        .map(|(p, c)| (p, c.to_string()))
        .collect();
    assert_eq!(listed, expected, "{report}");
    assert_eq!(report["used"], 5, "{report}");
    // The truncated file's message says what is wrong with it.
    let truncated = report["skipped"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["code"] == "malformed")
        .unwrap();
    assert!(
        truncated["message"].as_str().unwrap().contains("truncated"),
        "{truncated}"
    );

    // Append: the same kinds among later maps.
    let later = dir.path().join("later");
    std::fs::create_dir(&later).unwrap();
    let registry = FormatRegistry::with_default_formats();
    let added: Vec<PathBuf> = (9..18)
        .map(|i| {
            let path = later.join(format!("room_{}.bt", 1_451_865_600 + i * 600));
            registry
                .write_file(&frame(i), &path, WriteOptions::default())
                .unwrap();
            path
        })
        .collect();
    let mut expected = spoil(&added[2..6]);
    expected.sort();
    let report: serde_json::Value = serde_json::from_str(&ok(&[
        "append",
        "--quiet",
        "--json",
        "--skip-bad",
        s(&map),
        s(&later),
    ]))
    .unwrap();
    let mut listed = skipped_codes(&report);
    listed.sort();
    let expected: Vec<(PathBuf, String)> = expected
        .into_iter()
        .map(|(p, c)| (p, c.to_string()))
        .collect();
    assert_eq!(listed, expected, "{report}");
    assert_eq!(report["added"], 5, "{report}");
}
