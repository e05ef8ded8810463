//! Builds the C++ shim against the system OctoMap found by pkg-config.

use std::process::exit;

fn main() {
    println!("cargo:rerun-if-changed=src/bridge.rs");
    println!("cargo:rerun-if-changed=shim/octomap_shim.h");
    println!("cargo:rerun-if-changed=shim/octomap_shim.cc");
    println!("cargo:rerun-if-env-changed=PKG_CONFIG_PATH");

    let library = match pkg_config::Config::new()
        .atleast_version("1.9")
        .probe("octomap")
    {
        Ok(library) => library,
        Err(error) => {
            eprintln!(
                "error: the OctoMap C++ library (>= 1.9) was not found by pkg-config: {error}\n\
                 On Debian/Ubuntu install it with `sudo apt-get install liboctomap-dev`, \
                 or run `scripts/install-deps.sh`, which the README's commands call."
            );
            exit(1);
        }
    };

    let mut build = cxx_build::bridge("src/bridge.rs");
    build
        .file("shim/octomap_shim.cc")
        .std("c++14")
        // OctoMap's headers trip several warnings that are not ours to fix.
        .flag_if_supported("-Wno-deprecated-copy")
        .flag_if_supported("-Wno-unused-parameter")
        .flag_if_supported("-Wno-sign-compare");
    for path in &library.include_paths {
        build.include(path);
    }
    build.compile("froctomap_octomap_shim");
}
