//! The admin API end to end on the real binary and real sockets: upload a crop of the real
//! Tien Shan, build a dictionary from it, poll the job, create a world from a coarse base, fetch
//! its tiles (every layer and format), restart the server and fetch the same bytes. And crash
//! safety: SIGKILL in the middle of a dictionary build and in the middle of an upload, restart,
//! and the store is consistent (no partial object, earlier objects intact, the interrupted job
//! reported failed). And replicas: a world created on one process is served by another process
//! sharing its store within 5 s, without a restart, with the same bytes.

use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

use ndarray::{s, Array2};
use terrasynth_core::raster::{read_geotiff_file, Grid, ReadLimits};

use terrasynth_test_support::process::{delete, get, json, post};
use terrasynth_test_support::tile_of;

use crate::support::{start, Server};

pub(crate) const TOKEN: &str = "e2e-token";

/// A configuration without configured worlds (so no default dictionary is built at start).
fn config_file(dir: &Path) -> String {
    let p = dir.join("server.toml");
    std::fs::write(&p, "worlds = []\nbuild_queue = 4\n").unwrap();
    p.display().to_string()
}

fn serve(dir: &Path, store: &Path) -> Server {
    let cfg = config_file(dir);
    start(
        &["--config", &cfg],
        &[("TERRASYNTH_ADMIN_TOKEN", TOKEN)],
        store,
    )
}

pub(crate) fn tiff(grid: &Grid) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    terrasynth_core::raster::write_geotiff(grid, &mut out).unwrap();
    out.into_inner()
}

/// A window of the committed Tien Shan grid (the Kyrgyz Ala-Too), box-down-sampled `down` times.
pub(crate) fn tienshan_crop(col: usize, row: usize, side: usize, down: usize) -> Grid {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/data/tienshan_west_gebco15s.tif");
    let g = read_geotiff_file(&path, &ReadLimits::default()).unwrap();
    let crop = g
        .data
        .slice(s![row..row + side, col..col + side])
        .to_owned();
    let n = side / down;
    let data = Array2::from_shape_fn((n, n), |(r, c)| {
        let mut sum = 0.0;
        for dr in 0..down {
            for dc in 0..down {
                sum += crop[[r * down + dr, c * down + dc]];
            }
        }
        sum / (down * down) as f32
    });
    let georef = g
        .georef
        .window(col as i64, row as i64)
        .refined(1.0 / down as f64);
    Grid::new(data, georef)
}

pub(crate) fn upload(server: &Server, name: &str, bytes: &[u8]) -> String {
    let (st, body) = post(
        server,
        &format!("/admin/exemplars?name={name}"),
        TOKEN,
        "image/tiff",
        bytes,
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    json(&body)["id"].as_str().unwrap().to_string()
}

pub(crate) fn job(server: &Server, id: &str) -> serde_json::Value {
    let (st, body) = get(server, &format!("/admin/jobs/{id}"), Some(TOKEN));
    assert_eq!(st, 200, "{}", String::from_utf8_lossy(&body));
    json(&body)
}

pub(crate) fn wait_until(
    server: &Server,
    id: &str,
    done: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let deadline = Instant::now() + Duration::from_secs(600);
    loop {
        let j = job(server, id);
        if done(&j) {
            return j;
        }
        assert!(Instant::now() < deadline, "job {id}: {j}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Store files that are not complete objects: temporary leftovers.
fn leftovers(store: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for sub in ["exemplars", "dictionaries", "worlds", "aliases", "jobs"] {
        for e in std::fs::read_dir(store.join(sub)).unwrap().flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with(".tmp") {
                out.push(format!("{sub}/{n}"));
            }
        }
    }
    out
}

#[test]
fn upload_build_create_serve_restart_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let a = serve(dir.path(), &store);
    // The Kyrgyz Ala-Too south of Bishkek: a 128 × 128 crop at 15″ as the exemplar.
    let exemplar = upload(&a, "alatoo", &tiff(&tienshan_crop(1600, 600, 128, 1)));
    let (st, body) = post(
        &a,
        "/admin/dictionaries",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "alatoo", "exemplars": [exemplar], "atoms": 32, "patch": 16,
            "stride": 8, "learning": "medoids:2", "seed": 5})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 202, "{}", String::from_utf8_lossy(&body));
    let job_id = json(&body)["id"].as_str().unwrap().to_string();
    let done = wait_until(&a, &job_id, |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(done["state"], "succeeded", "{done}");
    let dict = done["result"].as_str().unwrap().to_string();
    // A coarse base: a neighbouring 256 × 256 window averaged to 1′ cells.
    let base = upload(&a, "coarse", &tiff(&tienshan_crop(1700, 700, 256, 4)));
    let (st, body) = post(
        &a,
        "/admin/worlds",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "mine", "base": base, "dictionaries": [dict], "max_zoom": 11})
            .to_string()
            .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let (st, info) = get(&a, "/worlds/mine", None);
    assert_eq!(st, 200);
    let info = json(&info);
    let layers: Vec<String> = info["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap().to_string())
        .collect();
    let native = info["native_zoom"].as_u64().unwrap() as u8;
    let [w, s_, e, n] = [0, 1, 2, 3].map(|i| info["bounds"][i].as_f64().unwrap());
    let (lon, lat) = (0.5 * (w + e), 0.5 * (s_ + n));
    let mut paths = Vec::new();
    for z in [native, native + 1, native + 2] {
        let (x, y) = tile_of(lon, lat, z);
        for layer in &layers {
            paths.push(format!("/tiles/mine/{layer}/{z}/{x}/{y}.png"));
        }
        paths.push(format!("/tiles/mine/elevation/{z}/{x}/{y}.exr"));
        paths.push(format!("/tiles/mine/elevation/{z}/{x}/{y}@2x.png"));
        paths.push(format!(
            "/tiles/mine/elevation/{z}/{x}/{y}.png?encoding=mapbox"
        ));
    }
    let first: Vec<Vec<u8>> = paths
        .iter()
        .map(|p| {
            let (st, body) = get(&a, p, None);
            assert_eq!(st, 200, "{p}");
            body
        })
        .collect();
    let heights = terrasynth_tiles::decode_terrarium_png(&first[0]).unwrap();
    // The native tile is larger than the base: pixels outside it hold the fill (0 m); inside,
    // the Kyrgyz Ala-Too rises from about 700 m to over 4000 m.
    let inside: Vec<f32> = heights.iter().copied().filter(|v| *v != 0.0).collect();
    let (lo, hi) = inside
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(
        inside.len() > 1000,
        "{} pixels inside the base",
        inside.len()
    );
    assert!(
        lo > 300.0 && hi < 5500.0 && hi - lo > 1000.0,
        "heights {lo}..{hi}"
    );
    a.kill();

    // A new process on the same store serves the same world and the same bytes.
    let b = serve(dir.path(), &store);
    for (p, want) in paths.iter().zip(&first) {
        let (st, body) = get(&b, p, None);
        assert_eq!(st, 200, "{p}");
        assert!(body == *want, "{p} differs after the restart");
    }
    assert_eq!(job(&b, &job_id)["state"], "succeeded");
    let (st, d) = get(&b, &format!("/dictionaries/{dict}"), None);
    assert_eq!((st, json(&d)["name"].as_str()), (200, Some("alatoo")));
    assert!(leftovers(&store).is_empty());
}

#[test]
fn sigkill_during_a_build_and_during_an_upload_leaves_a_consistent_store() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let a = serve(dir.path(), &store);
    let earlier = upload(
        &a,
        "earlier",
        &terrasynth_test_support::geotiff_bytes(64, 64, 1),
    );
    let big = upload(
        &a,
        "big",
        &terrasynth_test_support::geotiff_bytes(256, 256, 2),
    );
    let (st, body) = post(
        &a,
        "/admin/dictionaries",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "heavy", "exemplars": [big], "atoms": 2048, "stride": 1,
            "learning": "medoids:100"})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 202);
    let job_id = json(&body)["id"].as_str().unwrap().to_string();
    wait_until(&a, &job_id, |j| j["state"] == "running");
    a.kill();

    let b = serve(dir.path(), &store);
    let j = job(&b, &job_id);
    assert_eq!(j["state"], "failed", "{j}");
    assert!(j["error"].as_str().unwrap().contains("interrupted"));
    assert!(j["result"].is_null());
    let (_, d) = get(&b, "/dictionaries", None);
    assert!(
        json(&d).as_array().unwrap().is_empty(),
        "no partial dictionary listed"
    );
    let (_, list) = get(&b, "/admin/exemplars", Some(TOKEN));
    let ids: Vec<String> = json(&list)
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(ids.len(), 2);
    assert!(ids.contains(&earlier) && ids.contains(&big));

    // Kill it in the middle of an upload: headers and half of the body sent.
    let body = terrasynth_test_support::geotiff_bytes(512, 512, 3);
    let mut sock = std::net::TcpStream::connect(&b.addr).unwrap();
    write!(
        sock,
        "POST /admin/exemplars?name=partial HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {TOKEN}\r\nContent-Type: image/tiff\r\nContent-Length: {}\r\n\r\n",
        b.addr,
        body.len()
    )
    .unwrap();
    sock.write_all(&body[..body.len() / 2]).unwrap();
    sock.flush().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    b.kill();
    drop(sock);

    let c = serve(dir.path(), &store);
    let (_, list) = get(&c, "/admin/exemplars", Some(TOKEN));
    let list = json(&list);
    assert_eq!(list.as_array().unwrap().len(), 2, "{list}");
    assert!(list
        .as_array()
        .unwrap()
        .iter()
        .all(|e| e["name"] != "partial"));
    let (st, e) = get(&c, &format!("/admin/exemplars/{earlier}"), Some(TOKEN));
    assert_eq!((st, json(&e)["width"].as_u64()), (200, Some(64)));
    assert_eq!(job(&c, &job_id)["state"], "failed");
    assert!(leftovers(&store).is_empty());
    assert!(
        !store.join("corrupt").exists(),
        "nothing was found corrupted"
    );
    // The interrupted build can be resubmitted and the store still accepts writes.
    let (st, _) = post(
        &c,
        "/admin/exemplars?name=after",
        TOKEN,
        "image/tiff",
        &terrasynth_test_support::geotiff_bytes(32, 32, 4),
    );
    assert_eq!(st, 201);
}

#[test]
fn admin_disabled_without_a_token_on_the_real_binary() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config_file(dir.path());
    let s = start(&["--config", &cfg], &[], &dir.path().join("store"));
    let (st, body) = get(&s, "/admin/exemplars", Some("anything"));
    assert_eq!(st, 404);
    assert_eq!(json(&body)["status"], 404);
    let (st, body) = post(
        &s,
        "/admin/exemplars?name=x",
        "anything",
        "image/tiff",
        b"II*\0",
    );
    assert_eq!((st, json(&body)["status"].as_u64()), (404, Some(404)));
    assert_eq!(get(&s, "/openapi.json", None).0, 200);
}

#[test]
fn a_world_created_on_one_replica_is_served_by_another_sharing_the_store() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store");
    let a = serve(dir.path(), &store);
    let b = serve(dir.path(), &store);
    assert_eq!(get(&b, "/worlds/shared", None).0, 404);
    assert_eq!(get(&b, "/tiles/shared/elevation/9/0/0.png", None).0, 404);
    let exemplar = upload(&a, "alatoo", &tiff(&tienshan_crop(1600, 600, 128, 1)));
    let (st, body) = post(
        &a,
        "/admin/dictionaries",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "alatoo", "exemplars": [exemplar], "atoms": 32, "patch": 16,
            "stride": 8, "learning": "medoids:2", "seed": 5})
        .to_string()
        .as_bytes(),
    );
    assert_eq!(st, 202, "{}", String::from_utf8_lossy(&body));
    let job_id = json(&body)["id"].as_str().unwrap().to_string();
    let done = wait_until(&a, &job_id, |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(done["state"], "succeeded", "{done}");
    let dict = done["result"].as_str().unwrap().to_string();
    let base = upload(&a, "coarse", &tiff(&tienshan_crop(1700, 700, 256, 4)));
    let (st, body) = post(
        &a,
        "/admin/worlds",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "shared", "base": base, "dictionaries": [dict], "max_zoom": 11})
            .to_string()
            .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let created = Instant::now();
    // Replica b never saw the request: it finds the world in the store at its next request.
    let info = loop {
        let (st, body) = get(&b, "/worlds/shared", None);
        if st == 200 {
            break json(&body);
        }
        assert_eq!(st, 404);
        assert!(
            created.elapsed() < Duration::from_secs(5),
            "replica b does not serve the world 5 s after its creation"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    // The same description (TileJSON URLs name the replica asked).
    let mut on_a = json(&get(&a, "/worlds/shared", None).1);
    let mut on_b = info.clone();
    on_a.as_object_mut().unwrap().remove("tilejson");
    on_b.as_object_mut().unwrap().remove("tilejson");
    assert_eq!(on_a, on_b);
    let native = info["native_zoom"].as_u64().unwrap() as u8;
    let [w, s_, e, n] = [0, 1, 2, 3].map(|i| info["bounds"][i].as_f64().unwrap());
    for z in [native, native + 2] {
        let (x, y) = tile_of(0.5 * (w + e), 0.5 * (s_ + n), z);
        for p in [
            format!("/tiles/shared/elevation/{z}/{x}/{y}.png"),
            format!("/tiles/shared/color/{z}/{x}/{y}.png"),
        ] {
            let (sa, ba) = get(&a, &p, None);
            let (sb, bb) = get(&b, &p, None);
            assert_eq!((sa, sb), (200, 200), "{p}");
            assert!(ba == bb, "{p} differs between the replicas");
        }
    }
    // Names the store does not hold stay 404, however often they are asked.
    for _ in 0..3 {
        assert_eq!(get(&b, "/worlds/never-made", None).0, 404);
    }

    // A second world created on a appears in b's list without being asked for by name.
    let (st, body) = post(
        &a,
        "/admin/worlds",
        TOKEN,
        "application/json",
        serde_json::json!({"name": "listed", "base": base, "dictionaries": [dict], "max_zoom": 11})
            .to_string()
            .as_bytes(),
    );
    assert_eq!(st, 201, "{}", String::from_utf8_lossy(&body));
    let listed = |server: &Server, name: &str| {
        let (st, body) = get(server, "/worlds", None);
        assert_eq!(st, 200);
        json(&body)
            .as_array()
            .is_some_and(|ws| ws.iter().any(|w| w["name"] == name))
    };
    wait_for(
        || listed(&b, "listed"),
        "replica b lists the world a created",
    );

    // Deleted on a: b stops serving it, by name, in its list and in its tiles.
    let (x, y) = tile_of(0.5 * (w + e), 0.5 * (s_ + n), native);
    let tile = format!("/tiles/shared/elevation/{native}/{x}/{y}.png");
    assert_eq!(get(&b, &tile, None).0, 200);
    assert_eq!(delete(&a, "/admin/worlds/shared", TOKEN).0, 204);
    wait_for(
        || get(&b, "/worlds/shared", None).0 == 404,
        "replica b stops serving the world a deleted",
    );
    assert_eq!(get(&b, &tile, None).0, 404);
    assert!(!listed(&b, "shared"));
    assert!(listed(&b, "listed"));
}

/// Polls `done` every 100 ms; fails with `what` when it is still false after 5 s.
fn wait_for(mut done: impl FnMut() -> bool, what: &str) {
    let start = Instant::now();
    while !done() {
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "{what}: not within 5 s"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}
