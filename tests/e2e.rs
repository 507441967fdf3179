//! End to end on the real binary and real sockets: `terrasynth serve` on the embedded default
//! world builds its dictionary into a fresh store, serves plausible zoom-12 terrain over the
//! Tien Shan, and two separately started processes return byte-identical tiles (at the native
//! zoom and at amplified zooms). The second process reuses the store the first one filled.

use std::io::Read;
use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use terrasynth::tiles::decode_terrarium_png;

/// A server process, killed on drop.
struct Server {
    child: Child,
    base: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

fn start(store: &std::path::Path) -> Server {
    let port = free_port();
    let child = Command::new(env!("CARGO_BIN_EXE_terrasynth"))
        .args(["serve", "--listen", &format!("127.0.0.1:{port}")])
        .env("TERRASYNTH_STORE_DIR", store)
        .env("TERRASYNTH_CACHE_MB", "256")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start terrasynth serve");
    let server = Server {
        child,
        base: format!("http://127.0.0.1:{port}"),
    };
    let deadline = Instant::now() + Duration::from_secs(240);
    loop {
        if let Ok(r) = ureq::get(&format!("{}/healthz", server.base)).call() {
            if r.status() == 200 {
                return server;
            }
        }
        assert!(Instant::now() < deadline, "server did not become healthy");
        std::thread::sleep(Duration::from_millis(250));
    }
}

fn fetch(server: &Server, path: &str) -> (u16, Vec<u8>) {
    let resp = ureq::get(&format!("{}{path}", server.base))
        .config()
        .http_status_as_error(false)
        .build()
        .call()
        .expect("request");
    let status = resp.status().as_u16();
    let mut body = Vec::new();
    resp.into_body()
        .into_reader()
        .read_to_end(&mut body)
        .expect("body");
    (status, body)
}

#[test]
fn default_world_is_plausible_and_deterministic_across_processes() {
    let store = tempfile::tempdir().unwrap();
    // Zoom 12 over the Kyrgyz Ala-Too south of Bishkek (74.6°E, 42.55°N), zoom 8 (native), and
    // zoom 10 (amplified).
    let paths = [
        "/tiles/tienshan/elevation/12/2896/1512.png",
        "/tiles/tienshan/elevation/8/181/94.png",
        "/tiles/tienshan/elevation/10/724/378.png",
        "/tiles/tienshan/hillshade/10/724/378.png",
    ];
    let first: Vec<Vec<u8>> = {
        let a = start(store.path());
        let (status, json) = fetch(&a, "/worlds/tienshan");
        assert_eq!(status, 200);
        let v: serde_json::Value = serde_json::from_slice(&json).unwrap();
        assert_eq!(v["native_zoom"], 8);
        assert_eq!(v["maxzoom"], 16);
        paths
            .iter()
            .map(|p| {
                let (status, body) = fetch(&a, p);
                assert_eq!(status, 200, "{p}");
                body
            })
            .collect()
    };
    let heights = decode_terrarium_png(&first[0]).unwrap();
    assert_eq!(heights.dim(), (256, 256));
    let (lo, hi) = heights
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    // The Kyrgyz Ala-Too there rises from about 1000 m to over 4000 m.
    assert!(
        lo > 500.0 && hi < 5500.0 && hi - lo > 300.0,
        "heights {lo}..{hi}"
    );
    // A second process (reusing the store the first filled) returns the same bytes.
    let b = start(store.path());
    for (p, want) in paths.iter().zip(&first) {
        let (status, body) = fetch(&b, p);
        assert_eq!(status, 200, "{p}");
        assert!(body == *want, "{p} differs between processes");
    }
    // Errors on the real socket.
    assert_eq!(fetch(&b, "/tiles/tienshan/elevation/17/0/0.png").0, 404);
    assert_eq!(fetch(&b, "/tiles/tienshan/elevation/x/0/0.png").0, 400);
}
