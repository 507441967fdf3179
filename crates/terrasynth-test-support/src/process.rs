//! A `terrasynth serve` process on a free port for end-to-end tests, killed (SIGKILL) on drop, and
//! small HTTP helpers over ureq.

use std::io::Read;
use std::net::TcpListener;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A server process, killed on drop.
pub struct Server {
    /// The child process.
    pub child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// `127.0.0.1:PORT`.
    pub addr: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// Kills the process with SIGKILL and waits for it.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A free TCP port on 127.0.0.1.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// Starts `bin serve` (the `terrasynth` binary) in directory `cwd` with extra `args` and
/// environment `env`, its store in `store`, and waits for `/healthz`.
pub fn start_binary(
    bin: &Path,
    cwd: &Path,
    args: &[&str],
    env: &[(&str, &str)],
    store: &Path,
) -> Server {
    start_binary_with_output(bin, cwd, args, env, store, Stdio::null())
}

/// [`start_binary`] with the server's log (its standard output) written to the file `log`.
pub fn start_binary_logging(
    bin: &Path,
    cwd: &Path,
    args: &[&str],
    env: &[(&str, &str)],
    store: &Path,
    log: &Path,
) -> Server {
    let file = std::fs::File::create(log).expect("create the server's log file");
    start_binary_with_output(bin, cwd, args, env, store, Stdio::from(file))
}

fn start_binary_with_output(
    bin: &Path,
    cwd: &Path,
    args: &[&str],
    env: &[(&str, &str)],
    store: &Path,
    stdout: Stdio,
) -> Server {
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let mut cmd = Command::new(bin);
    cmd.arg("serve")
        .args(args)
        .args(["--listen", &addr])
        .env("TERRASYNTH_STORE_DIR", store)
        .env("TERRASYNTH_CACHE_MB", "64")
        .current_dir(cwd)
        .stdout(stdout)
        .stderr(Stdio::null());
    for (k, v) in env {
        cmd.env(k, v);
    }
    let child = cmd.spawn().expect("start terrasynth serve");
    let server = Server {
        child,
        base: format!("http://{addr}"),
        addr,
    };
    let deadline = Instant::now() + Duration::from_secs(240);
    loop {
        if let Ok(r) = ureq::get(&format!("{}/healthz", server.base)).call() {
            if r.status() == 200 {
                return server;
            }
        }
        assert!(Instant::now() < deadline, "server did not become healthy");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn finish(resp: Result<ureq::http::Response<ureq::Body>, ureq::Error>) -> (u16, Vec<u8>) {
    let resp = resp.expect("request");
    let status = resp.status().as_u16();
    let mut body = Vec::new();
    resp.into_body()
        .into_reader()
        .read_to_end(&mut body)
        .expect("body");
    (status, body)
}

/// `GET path` with an optional bearer token.
pub fn get(server: &Server, path: &str, token: Option<&str>) -> (u16, Vec<u8>) {
    let mut r = ureq::get(&format!("{}{path}", server.base))
        .config()
        .http_status_as_error(false)
        .build();
    if let Some(t) = token {
        r = r.header("Authorization", &format!("Bearer {t}"));
    }
    finish(r.call())
}

/// An answer with its headers (names lowercase; a repeated header's values joined by `, `).
pub struct Answer {
    /// The status code.
    pub status: u16,
    /// The headers by lowercase name.
    pub headers: std::collections::BTreeMap<String, String>,
    /// The body as sent (a `Content-Encoding` is not undone).
    pub body: Vec<u8>,
}

impl Answer {
    /// Header `name` (lowercase), or "" when absent.
    pub fn header(&self, name: &str) -> &str {
        self.headers.get(name).map_or("", String::as_str)
    }
}

/// `GET path` with the request headers `headers`, answered with its headers.
pub fn get_with(server: &Server, path: &str, headers: &[(&str, &str)]) -> Answer {
    let mut r = ureq::get(&format!("{}{path}", server.base))
        .config()
        .http_status_as_error(false)
        .build();
    for (k, v) in headers {
        r = r.header(*k, *v);
    }
    let resp = r.call().expect("request");
    let mut out = std::collections::BTreeMap::<String, String>::new();
    for (k, v) in resp.headers() {
        let v = String::from_utf8_lossy(v.as_bytes()).into_owned();
        out.entry(k.as_str().to_string())
            .and_modify(|s| {
                s.push_str(", ");
                s.push_str(&v);
            })
            .or_insert(v);
    }
    let (status, body) = finish(Ok(resp));
    Answer {
        status,
        headers: out,
        body,
    }
}

/// `POST path` with a body of `content_type` and a bearer token.
pub fn post(
    server: &Server,
    path: &str,
    token: &str,
    content_type: &str,
    body: &[u8],
) -> (u16, Vec<u8>) {
    let r = ureq::post(&format!("{}{path}", server.base))
        .config()
        .http_status_as_error(false)
        .build()
        .header("Authorization", &format!("Bearer {token}"))
        .header("Content-Type", content_type);
    finish(r.send(body))
}

/// `DELETE path` with a bearer token.
pub fn delete(server: &Server, path: &str, token: &str) -> (u16, Vec<u8>) {
    let r = ureq::delete(&format!("{}{path}", server.base))
        .config()
        .http_status_as_error(false)
        .build()
        .header("Authorization", &format!("Bearer {token}"));
    finish(r.call())
}

/// The JSON of a body.
pub fn json(body: &[u8]) -> serde_json::Value {
    serde_json::from_slice(body).unwrap_or(serde_json::Value::Null)
}
