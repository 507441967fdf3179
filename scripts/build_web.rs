//! Build script (`build = "scripts/build_web.rs"` in Cargo.toml): makes sure the web map's
//! pinned front-end dependencies (MapLibre GL JS and playwright-core, `package-lock.json`) are installed in `node_modules`, so that a plain
//! `cargo run --release` in a fresh clone serves a working map at `/`. It runs
//! `scripts/install_web.sh` (`npm ci`) only when `package-lock.json` is newer than the install,
//! and never fails the build: without npm, or offline, it prints a warning and the page explains
//! how to install MapLibre. Set `TERRASYNTH_SKIP_WEB_INSTALL=1` to skip it.

use std::path::Path;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=package-lock.json");
    println!("cargo:rerun-if-changed=package.json");
    println!("cargo:rerun-if-env-changed=TERRASYNTH_SKIP_WEB_INSTALL");
    if std::env::var_os("TERRASYNTH_SKIP_WEB_INSTALL").is_some() {
        return;
    }
    let root = match std::env::var_os("CARGO_MANIFEST_DIR") {
        Some(d) => std::path::PathBuf::from(d),
        None => return,
    };
    let lock = root.join("package-lock.json");
    let installed = root.join("node_modules").join(".package-lock.json");
    if !lock.exists() || is_newer(&installed, &lock) {
        return;
    }
    // Cargo shows a build script's output only when it ends: say afterwards what took the time.
    let started = std::time::Instant::now();
    let status = Command::new("bash")
        .arg(root.join("scripts").join("install_web.sh"))
        .current_dir(&root)
        .status();
    match status {
        Ok(s) if s.success() => println!(
            "cargo:warning=installed the web map's npm packages (MapLibre GL JS, playwright-core) with scripts/install_web.sh in {:.0} s; later builds skip it",
            started.elapsed().as_secs_f64()
        ),
        Ok(s) => println!(
            "cargo:warning=scripts/install_web.sh failed ({s}); the web map at / needs MapLibre: run it by hand"
        ),
        Err(e) => println!(
            "cargo:warning=cannot run scripts/install_web.sh ({e}); the web map at / needs MapLibre: run it by hand"
        ),
    }
}

/// Whether `a` exists and was modified after `b`.
fn is_newer(a: &Path, b: &Path) -> bool {
    let time = |p: &Path| p.metadata().and_then(|m| m.modified()).ok();
    match (time(a), time(b)) {
        (Some(ta), Some(tb)) => ta > tb,
        _ => false,
    }
}
