//! The `froctomap` binary end to end: output, exit codes, messages, atomic outputs, and no
//! OctoMap debug chatter on the terminal.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests fail by panicking

use froctomap_test_support::{compare_octrees, convert_octree, geb079, octomap_fixture, scratch};
use std::path::Path;
use std::process::{Command, Output};

fn froctomap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_froctomap"))
        .args(args)
        .output()
        .expect("run froctomap")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn path_str(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

#[test]
fn info_describes_geb079() {
    let out = froctomap(&["info", path_str(&geb079())]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    for expected in [
        "format:          bt",
        "resolution:      0.08 m",
        "nodes:           532,566",
        "leaves:          428,144 (occupied 143,729, free 284,415)",
        "known voxels:    1,136,432 (occupied 185,673, free 950,759)",
    ] {
        assert!(
            stdout.contains(expected),
            "missing {expected:?} in:\n{stdout}"
        );
    }
    assert!(out.stderr.is_empty(), "stderr: {}", text(&out.stderr));
}

#[test]
fn info_json_agrees_with_upstream_counts() {
    let out = froctomap(&["info", "--json", path_str(&geb079())]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(json["format"], "bt");
    assert_eq!(json["leaves"], 428_144);
    // compare_octrees expands the tree and counts voxels independently.
    let dir = scratch();
    let ot = dir.path().join("geb.ot");
    convert_octree(&geb079(), &ot);
    let upstream_voxels = compare_octrees(&ot, &ot).expanded_leaves.expect("count");
    assert_eq!(json["voxels"], upstream_voxels);
    let bounds = &json["known_bounds_m"];
    assert_eq!(bounds["min"][0], -8.0);
    assert!(json["warnings"].as_array().unwrap().is_empty());
}

#[test]
fn bt_to_ot_to_bt_matches_upstream_and_stays_quiet() {
    let dir = scratch();
    let ot = dir.path().join("geb.ot");
    let bt = dir.path().join("geb.bt");
    let upstream_ot = dir.path().join("upstream.ot");
    for (input, output) in [(geb079(), ot.clone()), (ot.clone(), bt.clone())] {
        let out = froctomap(&["convert", path_str(&input), path_str(&output)]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let stderr = text(&out.stderr);
        assert!(stderr.contains("428,144 leaves"), "{stderr}");
        assert!(
            !stderr.contains("Writing") && !stderr.contains("Reading"),
            "library chatter leaked: {stderr}"
        );
    }
    convert_octree(&geb079(), &upstream_ot);
    assert_eq!(
        std::fs::read(&ot).unwrap(),
        std::fs::read(&upstream_ot).unwrap()
    );
    assert_eq!(
        std::fs::read(&bt).unwrap(),
        std::fs::read(geb079()).unwrap()
    );
    let quiet = froctomap(&["convert", "--quiet", path_str(&ot), path_str(&bt)]);
    assert!(quiet.status.success() && quiet.stderr.is_empty());
}

#[test]
fn format_flag_overrides_the_extension() {
    let dir = scratch();
    let out_path = dir.path().join("map.octomap");
    let out = froctomap(&[
        "convert",
        path_str(&octomap_fixture("few_voxels.ot")),
        path_str(&out_path),
        "--format",
        "bt",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(std::fs::read(&out_path)
        .unwrap()
        .starts_with(b"# Octomap OcTree binary file\n"));
    let unknown = froctomap(&[
        "convert",
        path_str(&octomap_fixture("few_voxels.ot")),
        path_str(&out_path),
    ]);
    assert!(!unknown.status.success());
    let stderr = text(&unknown.stderr);
    assert!(
        stderr.contains("map.octomap") && stderr.contains("--format"),
        "{stderr}"
    );
    let bad = froctomap(&[
        "convert",
        path_str(&octomap_fixture("few_voxels.ot")),
        path_str(&out_path),
        "--format",
        "png",
    ]);
    assert!(text(&bad.stderr).contains("unknown map format `png` (known: bt, ot)"));
}

#[test]
fn errors_name_the_file_and_exit_nonzero() {
    let dir = scratch();
    let truncated = dir.path().join("cut.bt");
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 3]).unwrap();
    let out = froctomap(&["info", path_str(&truncated)]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(
        stderr.starts_with(&format!("error: {}: truncated", truncated.display())),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());

    let renamed = dir.path().join("renamed.ot");
    std::fs::write(&renamed, &bytes).unwrap();
    let forced = froctomap(&["info", "--input-format", "ot", path_str(&renamed)]);
    assert!(
        text(&forced.stderr).contains("this is a .bt file"),
        "{}",
        text(&forced.stderr)
    );
    let detected = froctomap(&["info", path_str(&renamed)]);
    assert!(detected.status.success());
    assert!(
        text(&detected.stderr).contains("warning:"),
        "{}",
        text(&detected.stderr)
    );
}

#[test]
fn failed_conversion_leaves_no_output_behind() {
    let dir = scratch();
    let existing = dir.path().join("keep.ot");
    std::fs::write(&existing, b"previous content").unwrap();
    let bad_input = dir.path().join("bad.bt");
    std::fs::write(
        &bad_input,
        b"# Octomap OcTree binary file\nid OcTree\nsize 5\nres 0.1\ndata\n\x03",
    )
    .unwrap();
    let out = froctomap(&["convert", path_str(&bad_input), path_str(&existing)]);
    assert!(!out.status.success());
    assert_eq!(std::fs::read(&existing).unwrap(), b"previous content");
    let unwritable = froctomap(&[
        "convert",
        path_str(&octomap_fixture("few_voxels.bt")),
        "/nonexistent-dir/out.ot",
    ]);
    assert!(!unwritable.status.success());
    assert!(
        text(&unwritable.stderr).contains("/nonexistent-dir/out.ot"),
        "{}",
        text(&unwritable.stderr)
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 2, "temporary files left: {leftovers:?}");
}

#[test]
fn formats_lists_both_backends_native_first() {
    let out = froctomap(&["formats"]);
    assert!(out.status.success());
    let stdout = text(&out.stdout);
    let line_of = |needle: &str| {
        stdout
            .lines()
            .position(|line| line.starts_with(needle))
            .unwrap_or_else(|| panic!("no line starting with {needle:?} in:\n{stdout}"))
    };
    for name in ["bt", "ot"] {
        let native = line_of(&format!("{name:<7} native   .{name}"));
        let upstream = line_of(&format!("{name:<7} octomap  .{name}"));
        assert!(
            native < upstream,
            "native is the default, listed first:\n{stdout}"
        );
    }
    // Recording formats are listed once each, ROS 1 bags, ROS 2 bag directories and MCAP
    // as writable too.
    assert!(stdout
        .lines()
        .nth(line_of("rosbag "))
        .unwrap()
        .contains(" rec,w "));
    assert!(stdout
        .lines()
        .nth(line_of("ros2bag "))
        .unwrap()
        .contains(" rec,w "));
    assert!(stdout
        .lines()
        .nth(line_of("mcap "))
        .unwrap()
        .contains(" rec,w "));
    assert_eq!(stdout.matches("\nmcap ").count(), 1, "{stdout}");

    // `--json` lists the same rows, in the same order, as data.
    let out = froctomap(&["formats", "--json"]);
    assert!(out.status.success());
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    let names: Vec<&str> = stdout
        .lines()
        .skip(1)
        .map(|l| l.split(' ').next().unwrap())
        .collect();
    let json_names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(json_names, names);
    let row = |name: &str, backend: serde_json::Value| {
        rows.iter()
            .find(|r| r["name"] == name && r["backend"] == backend)
            .unwrap_or_else(|| panic!("no {name} in {rows:?}"))
            .clone()
    };
    assert_eq!(
        row("bt", "native".into()),
        serde_json::json!({"name": "bt", "kind": "map", "backend": "native", "extensions": ["bt"],
            "read": true, "write": true,
            "description": "OctoMap binary tree (.bt): maximum-likelihood states, native Rust codec"})
    );
    assert_eq!(row("froct", serde_json::Value::Null)["kind"], "series");
    let bag = row("ros2bag", serde_json::Value::Null);
    assert_eq!(
        (&bag["kind"], &bag["extensions"], &bag["write"]),
        (&"recording".into(), &serde_json::json!([]), &true.into())
    );
}

/// `--backend octomap` selects the C++ library; it must tell exactly the same story as the
/// native default: same info (only the format description names the backend), same bytes
/// written, same warnings and errors.
#[test]
fn both_backends_give_identical_info_and_conversions() {
    let dir = scratch();
    let info = |backend: &str, file: &Path| -> serde_json::Value {
        let out = froctomap(&["--backend", backend, "info", "--json", path_str(file)]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        serde_json::from_slice(&out.stdout).expect("valid JSON")
    };
    for file in [
        geb079(),
        octomap_fixture("coarse_leaves.ot"),
        octomap_fixture("size_mismatch.bt"),
    ] {
        let mut native = info("native", &file);
        let mut upstream = info("octomap", &file);
        let description = |v: &mut serde_json::Value| {
            v["format_description"].take().as_str().unwrap().to_string()
        };
        assert!(description(&mut native).contains("native Rust"));
        assert!(description(&mut upstream).contains("upstream C++"));
        assert_eq!(native, upstream, "{}", file.display());
    }
    // The default is native.
    let default = froctomap(&["info", path_str(&geb079())]);
    assert!(text(&default.stdout).contains("native Rust codec"));

    let (native_ot, upstream_ot) = (dir.path().join("n.ot"), dir.path().join("u.ot"));
    let (native_bt, upstream_bt) = (dir.path().join("n.bt"), dir.path().join("u.bt"));
    for (backend, input, output) in [
        ("native", geb079(), &native_ot),
        ("octomap", geb079(), &upstream_ot),
        ("native", native_ot.clone(), &native_bt),
        ("octomap", upstream_ot.clone(), &upstream_bt),
    ] {
        let out = froctomap(&[
            "convert",
            "--backend",
            backend,
            path_str(&input),
            path_str(output),
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
    assert_eq!(
        std::fs::read(&native_ot).unwrap(),
        std::fs::read(&upstream_ot).unwrap()
    );
    assert_eq!(
        std::fs::read(&native_bt).unwrap(),
        std::fs::read(&upstream_bt).unwrap()
    );
    assert_eq!(
        std::fs::read(&native_bt).unwrap(),
        std::fs::read(geb079()).unwrap()
    );

    // Errors read the same.
    let truncated = dir.path().join("cut.bt");
    let bytes = std::fs::read(octomap_fixture("few_voxels.bt")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() - 3]).unwrap();
    let errors: Vec<String> = ["native", "octomap"]
        .iter()
        .map(|backend| {
            let out = froctomap(&["--backend", backend, "info", path_str(&truncated)]);
            assert_eq!(out.status.code(), Some(1));
            text(&out.stderr)
        })
        .collect();
    assert_eq!(errors[0], errors[1]);

    let bad = froctomap(&["--backend", "cxx", "formats"]);
    assert!(!bad.status.success());
    assert!(
        text(&bad.stderr).contains("octomap"),
        "{}",
        text(&bad.stderr)
    );
}

/// The small things a new user met: `-q` silences the summary, a build larger than its
/// inputs says so, `--json` numbers carry no float noise, a zero duration is named as one,
/// `build --help` keeps its examples apart.
#[test]
fn summaries_ratios_json_numbers_durations_and_help_read_right() {
    let scratch_dir = scratch();
    let dir = scratch_dir.path();
    let map = octomap_fixture("few_voxels.bt");
    let out = dir.join("tiny.froct");
    let build = |quiet: bool, json: bool| {
        let mut args = vec!["build", path_str(&map), "--start", "2016-01-04T00:00:00Z"];
        args.extend(["--step", "1h", "-o", path_str(&out)]);
        if quiet {
            args.insert(0, "-q");
        }
        if json {
            args.push("--json");
        }
        let output = froctomap(&args);
        assert!(output.status.success(), "{}", text(&output.stderr));
        text(&output.stdout)
    };
    assert_eq!(build(true, false), "");
    let summary = build(false, false);
    let bytes = std::fs::metadata(&out).unwrap().len();
    let input = std::fs::metadata(&map).unwrap().len();
    assert!(bytes > input, "{bytes} vs {input}");
    assert!(summary.contains("x larger"), "{summary}");
    assert!(!summary.contains("smaller"), "{summary}");
    json_floats_read_back_as_printed(&build(true, true), &out);
    zero_durations_are_named(dir, &out);
    retrieve_reports_json_beside_the_map(dir, &out);
    predict_and_export_report_json(dir, &out);
    let help = text(&froctomap(&["build", "--help"]).stdout);
    assert!(
        help.contains("\n\nfroctomap build maps/ -o office.froct\n\nfroctomap build 'scans/*.bt'"),
        "{help}"
    );
}

/// Every float of a --json report reads back as printed: no `1.6800000000000002`
/// (`build_report`: a build's; then `info` of a map and of `froct`).
fn json_floats_read_back_as_printed(build_report: &str, froct: &Path) {
    fn floats(value: &serde_json::Value, out: &mut Vec<f64>) {
        match value {
            serde_json::Value::Number(n) if !(n.is_i64() || n.is_u64()) => {
                out.push(n.as_f64().unwrap())
            }
            serde_json::Value::Array(items) => items.iter().for_each(|v| floats(v, out)),
            serde_json::Value::Object(fields) => fields.values().for_each(|v| floats(v, out)),
            _ => {}
        }
    }
    for report in [
        build_report.to_string(),
        text(&froctomap(&["info", "--json", path_str(&geb079())]).stdout),
        text(&froctomap(&["info", "--json", path_str(froct)]).stdout),
    ] {
        let mut found = Vec::new();
        floats(&serde_json::from_str(&report).unwrap(), &mut found);
        assert!(!found.is_empty());
        for x in found {
            assert_eq!(froctomap_convert::tidy_float(x), x, "{report}");
        }
    }
}

/// A zero `--every` is named as one, and nothing is written.
fn zero_durations_are_named(dir: &Path, out: &Path) {
    let zero = froctomap(&[
        "export",
        path_str(out),
        "--from",
        "2016-01-04T00:00:00Z",
        "--to",
        "2016-01-04T01:00:00Z",
        "--every",
        "0s",
        "-o",
        path_str(&dir.join("none")),
    ]);
    assert!(
        text(&zero.stderr).contains("cannot read \"0s\" as a duration: zero"),
        "{}",
        text(&zero.stderr)
    );
    assert!(!dir.join("none").exists());
}

fn retrieve_reports_json_beside_the_map(dir: &Path, out: &Path) {
    // --json of retrieve, predict and export; with `-o -` the report goes to stderr and the
    // map's bytes alone to stdout.
    let file_out = dir.join("then.bt");
    let report = text(
        &froctomap(&[
            "retrieve",
            path_str(out),
            "--time",
            "last",
            "-o",
            path_str(&file_out),
            "--json",
        ])
        .stdout,
    );
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(
        (report["kind"].as_str(), report["sample"].as_u64()),
        (Some("observed"), Some(0))
    );
    let piped = froctomap(&[
        "retrieve",
        path_str(out),
        "--time",
        "last",
        "-o",
        "-",
        "--format",
        "bt",
        "--json",
    ]);
    assert_eq!(piped.stdout, std::fs::read(&file_out).unwrap());
    let report: serde_json::Value = serde_json::from_str(&text(&piped.stderr)).unwrap();
    assert_eq!(
        report["leaves"],
        report["leaves"].as_u64().filter(|&n| n > 0).unwrap()
    );
}

/// `--json` of predict and export.
fn predict_and_export_report_json(dir: &Path, out: &Path) {
    let predicted = text(
        &froctomap(&[
            "predict",
            path_str(out),
            "--time",
            "2016-02-01T00:00:00Z",
            "-o",
            path_str(&dir.join("later.ot")),
            "--json",
        ])
        .stdout,
    );
    let predicted: serde_json::Value = serde_json::from_str(&predicted).unwrap();
    assert_eq!(
        (
            predicted["kind"].as_str(),
            predicted["within_span"].as_bool()
        ),
        (Some("predicted"), Some(false))
    );
    let exported = text(
        &froctomap(&[
            "export",
            path_str(out),
            "--from",
            "2016-01-04T00:00:00Z",
            "--to",
            "2016-01-04T02:00:00Z",
            "--every",
            "1h",
            "-o",
            path_str(&dir.join("series")),
            "--json",
        ])
        .stdout,
    );
    let exported: serde_json::Value = serde_json::from_str(&exported).unwrap();
    assert_eq!(exported["maps"].as_array().map(Vec::len), Some(3));
    for map in exported["maps"].as_array().unwrap() {
        assert!(Path::new(map["path"].as_str().unwrap()).is_file());
    }
}
