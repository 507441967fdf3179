//! The mutation run of issue #14 (acceptance 3): uploads mutated GeoTIFF, 16-bit PNG and OpenEXR
//! files to a running server's admin API and checks that no upload is answered 5xx or breaks the
//! connection (a panic), and that the store holds exactly what it held before — uploads that are
//! accepted (a flipped bit in the pixels still makes a valid raster) are deleted again at once,
//! and the store's files (names and sizes) are compared with the first listing every 1,000
//! uploads and at the end.
//!
//! Mutations, chosen at random (deterministic for a seed): 1–16 random bit flips anywhere; a
//! truncation at a random length; header edits (1–8 bytes of the first 512 replaced by 0x00,
//! 0xFF, 0x7F, 0x80 or a random byte, or a 32-bit field set to 0, 1, 0x7FFFFFFF or 0xFFFFFFFF);
//! a random slice duplicated or removed. The content type is the seed's (sometimes none, to make
//! the server sniff).
//!
//! Usage (scripts/mutation_run.sh starts the server and runs this):
//! `cargo run --example mutation_run -- --base http://127.0.0.1:PORT --token TOKEN
//! --store STORE_DIR [--count 100000] [--threads 2] [--seed 14]`.

// A measurement tool: a failed unwrap aborts the run with its message.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, RwLock};
use std::time::Instant;

use terrasynth_test_support::{exr_bytes, geotiff_bytes, png16_bytes};

/// SplitMix64: a small deterministic generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// A seed file: its bytes, content type and the query its upload needs.
struct Seed {
    bytes: Vec<u8>,
    content_type: &'static str,
    query: &'static str,
}

fn mutate(rng: &mut Rng, seed: &[u8]) -> (Vec<u8>, &'static str) {
    let mut b = seed.to_vec();
    match rng.below(5) {
        0 => {
            for _ in 0..1 + rng.below(16) {
                let i = rng.below(b.len());
                b[i] ^= 1 << rng.below(8);
            }
            (b, "bit flips")
        }
        1 => {
            b.truncate(rng.below(b.len()));
            (b, "truncation")
        }
        2 => {
            let head = b.len().min(512);
            for _ in 0..1 + rng.below(8) {
                let i = rng.below(head);
                b[i] = match rng.below(5) {
                    0 => 0x00,
                    1 => 0xFF,
                    2 => 0x7F,
                    3 => 0x80,
                    _ => rng.next() as u8,
                };
            }
            (b, "header bytes")
        }
        3 => {
            let head = b.len().min(512).saturating_sub(4);
            let i = rng.below(head);
            let v: u32 = [0, 1, 0x7FFF_FFFF, 0xFFFF_FFFF][rng.below(4)];
            let bytes = if rng.below(2) == 0 {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            };
            b[i..i + 4].copy_from_slice(&bytes);
            (b, "header field")
        }
        _ => {
            let i = rng.below(b.len());
            let n = 1 + rng.below(256.min(b.len() - i));
            if rng.below(2) == 0 {
                let slice = b[i..i + n].to_vec();
                b.splice(i..i, slice);
                (b, "slice duplicated")
            } else {
                b.drain(i..i + n);
                (b, "slice removed")
            }
        }
    }
}

#[derive(Default)]
struct Tally {
    statuses: Mutex<BTreeMap<u16, u64>>,
    by_mutation: Mutex<BTreeMap<(&'static str, u16), u64>>,
    broken: AtomicU64,
    server_errors: AtomicU64,
    store_changes: AtomicU64,
    done: AtomicU64,
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let base = arg(&args, "--base").expect("--base http://127.0.0.1:PORT");
    assert!(
        base.starts_with("http://127.0.0.1:") || base.starts_with("http://localhost:"),
        "loopback only"
    );
    let token = arg(&args, "--token").expect("--token");
    let store = PathBuf::from(arg(&args, "--store").expect("--store DIR"));
    let count: u64 = arg(&args, "--count").map_or(100_000, |v| v.parse().unwrap());
    let threads: u64 = arg(&args, "--threads").map_or(2, |v| v.parse().unwrap());
    let seed: u64 = arg(&args, "--seed").map_or(14, |v| v.parse().unwrap());

    let georef = "&cell_size=0.004166666666666667&west=74&north=43";
    let seeds = [
        Seed {
            bytes: geotiff_bytes(48, 48, 1),
            content_type: "image/tiff",
            query: "",
        },
        Seed {
            bytes: png16_bytes(48, 48, 2),
            content_type: "image/png",
            query: georef,
        },
        Seed {
            bytes: exr_bytes(48, 48, 3),
            content_type: "image/x-exr",
            query: georef,
        },
    ];
    let before = store_files(&store);
    let tally = Tally::default();
    // Uploads (with the deletion of an accepted one) hold it shared; the store check holds it
    // alone, so that it never sees an upload in flight.
    let gate = RwLock::new(());
    let start = Instant::now();
    std::thread::scope(|s| {
        for t in 0..threads {
            let (seeds, tally, before, store, gate) = (&seeds, &tally, &before, &store, &gate);
            let (base, token) = (&base, &token);
            s.spawn(move || {
                let agent: ureq::Agent = ureq::Agent::config_builder()
                    .http_status_as_error(false)
                    .build()
                    .into();
                let mut rng = Rng(seed.wrapping_mul(1000).wrapping_add(t));
                loop {
                    let i = tally.done.fetch_add(1, Ordering::Relaxed);
                    if i >= count {
                        break;
                    }
                    let in_flight = gate.read().unwrap();
                    let seed = &seeds[rng.below(seeds.len())];
                    let (body, what) = mutate(&mut rng, &seed.bytes);
                    let url = format!("{base}/admin/exemplars?name=m{i}{}", seed.query);
                    let mut req = agent
                        .post(&url)
                        .header("Authorization", &format!("Bearer {token}"));
                    if rng.below(10) != 0 {
                        req = req.header("Content-Type", seed.content_type);
                    } else {
                        req = req.header("Content-Type", "application/octet-stream");
                    }
                    let status = match req.send(&body[..]) {
                        Ok(resp) => {
                            let status = resp.status().as_u16();
                            let mut text = String::new();
                            let _ = resp.into_body().into_reader().read_to_string(&mut text);
                            if status == 201 {
                                let id = serde_json::from_str::<serde_json::Value>(&text)
                                    .ok()
                                    .and_then(|v| v["id"].as_str().map(String::from))
                                    .unwrap_or_default();
                                // Accepted: remove it again, so that the store must come back
                                // to what it was.
                                let del = agent
                                    .delete(&format!("{base}/admin/exemplars/{id}"))
                                    .header("Authorization", &format!("Bearer {token}"))
                                    .call();
                                if !del.is_ok_and(|r| r.status().as_u16() == 204) {
                                    tally.store_changes.fetch_add(1, Ordering::Relaxed);
                                }
                            }
                            status
                        }
                        Err(e) => {
                            eprintln!("upload {i} ({what}): {e}");
                            tally.broken.fetch_add(1, Ordering::Relaxed);
                            0
                        }
                    };
                    if status >= 500 {
                        tally.server_errors.fetch_add(1, Ordering::Relaxed);
                        eprintln!("upload {i} ({what}): {status}");
                    }
                    *tally.statuses.lock().unwrap().entry(status).or_default() += 1;
                    *tally
                        .by_mutation
                        .lock()
                        .unwrap()
                        .entry((what, status))
                        .or_default() += 1;
                    drop(in_flight);
                    if i % 1000 == 999 {
                        let _alone = gate.write().unwrap();
                        if differs(store, before) {
                            tally.store_changes.fetch_add(1, Ordering::Relaxed);
                            eprintln!("after {i} uploads the store differs");
                        }
                        eprintln!("{} uploads, {:.0} s", i + 1, start.elapsed().as_secs_f64());
                    }
                }
            });
        }
    });
    let end_differs = differs(&store, &before);
    if end_differs {
        tally.store_changes.fetch_add(1, Ordering::Relaxed);
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "uploads {count} in {secs:.0} s ({:.0}/s); statuses {:?}",
        count as f64 / secs,
        tally.statuses.lock().unwrap()
    );
    println!(
        "5xx {}; broken connections {}; store changes {}",
        tally.server_errors.load(Ordering::Relaxed),
        tally.broken.load(Ordering::Relaxed),
        tally.store_changes.load(Ordering::Relaxed)
    );
    for ((what, status), n) in tally.by_mutation.lock().unwrap().iter() {
        println!("  {what:<17} {status}: {n}");
    }
    let failed = tally.server_errors.load(Ordering::Relaxed)
        + tally.broken.load(Ordering::Relaxed)
        + tally.store_changes.load(Ordering::Relaxed);
    if failed > 0 {
        std::process::exit(1);
    }
}

/// Every file of the store (every subdirectory: objects, aliases, jobs, spooled uploads,
/// quarantine) with its size.
fn store_files(store: &Path) -> BTreeMap<String, u64> {
    let mut out = BTreeMap::new();
    let mut dirs = vec![store.to_path_buf()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                dirs.push(p);
            } else {
                let len = e.metadata().map(|m| m.len()).unwrap_or(0);
                let name = p.strip_prefix(store).unwrap_or(&p).display().to_string();
                out.insert(name, len);
            }
        }
    }
    out
}

/// Whether the store's files (names and sizes) differ from `before`.
fn differs(store: &Path, before: &BTreeMap<String, u64>) -> bool {
    let now = store_files(store);
    if now != *before {
        for (k, v) in &now {
            if before.get(k) != Some(v) {
                eprintln!("  store: {k} ({v} bytes) is new or changed");
            }
        }
        for k in before.keys().filter(|k| !now.contains_key(*k)) {
            eprintln!("  store: {k} is gone");
        }
    }
    now != *before
}
