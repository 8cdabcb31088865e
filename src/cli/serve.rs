//! `radbake serve <bake dir>`: the three.js viewer (`web/`) and a bake's
//! files on 127.0.0.1, so a bake can be looked at in a browser with one
//! command. The viewer page, radbake's three.js plugin and the pinned
//! three.js files it needs are compiled into the binary; the bake folder's
//! files are served under `/bake/` (plain file names only: no paths, no
//! `..`).

use super::Outcome;
use clap::Args;
use std::path::{Path, PathBuf};

/// `radbake serve` arguments.
#[derive(Args)]
pub struct ServeArgs {
    /// The bake folder (`radbake bake --out`).
    pub dir: PathBuf,
    /// Port on 127.0.0.1.
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Serve this many requests, then exit (for scripts and tests).
    #[arg(long, hide = true)]
    pub requests: Option<u64>,
}

/// The viewer's files: (URL path, MIME type, bytes).
const FILES: &[(&str, &str, &[u8])] = &[
    ("/", "text/html", include_bytes!("../../web/index.html")),
    (
        "/index.html",
        "text/html",
        include_bytes!("../../web/index.html"),
    ),
    (
        "/viewer.js",
        "text/javascript",
        include_bytes!("../../web/viewer.js"),
    ),
    (
        "/radbake-three.js",
        "text/javascript",
        include_bytes!("../../web/radbake-three.js"),
    ),
    (
        "/radbake-live.js",
        "text/javascript",
        include_bytes!("../../web/radbake-live.js"),
    ),
    (
        "/vendor/three/build/three.module.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/build/three.module.js"),
    ),
    (
        "/vendor/three/build/three.core.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/build/three.core.js"),
    ),
    (
        "/vendor/three/examples/jsm/loaders/GLTFLoader.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    ),
    (
        "/vendor/three/examples/jsm/loaders/EXRLoader.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/loaders/EXRLoader.js"),
    ),
    (
        "/vendor/three/examples/jsm/libs/fflate.module.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/libs/fflate.module.js"),
    ),
    (
        "/vendor/three/examples/jsm/controls/OrbitControls.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/controls/OrbitControls.js"),
    ),
    (
        "/vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    ),
    (
        "/vendor/three/examples/jsm/utils/SkeletonUtils.js",
        "text/javascript",
        include_bytes!("../../web/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    ),
];

/// MIME type of a bake file.
fn mime(name: &str) -> &'static str {
    match name.rsplit('.').next().unwrap_or("") {
        "glb" => "model/gltf-binary",
        "gltf" | "json" => "application/json",
        "png" => "image/png",
        _ => "application/octet-stream",
    }
}

/// The bytes and type for `url` (without its query), or None (404).
fn resolve(dir: &Path, url: &str) -> Option<(Vec<u8>, &'static str)> {
    let path = url.split('?').next().unwrap_or("");
    if let Some((_, m, bytes)) = FILES.iter().find(|(p, _, _)| *p == path) {
        return Some((bytes.to_vec(), m));
    }
    let name = path.strip_prefix("/bake/")?;
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'));
    if !plain {
        return None;
    }
    let file = dir.join(name);
    file.is_file()
        .then(|| std::fs::read(&file).ok())
        .flatten()
        .map(|b| (b, mime(name)))
}

/// Runs `radbake serve`.
pub fn run(args: &ServeArgs) -> Outcome {
    if !args.dir.is_dir() {
        return Err((1, format!("{}: not a folder", args.dir.display())));
    }
    let addr = format!("127.0.0.1:{}", args.port);
    let listener = std::net::TcpListener::bind(&addr).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AddrInUse {
            (
                3,
                format!("{addr} is in use: choose another port with --port"),
            )
        } else {
            (3, format!("cannot listen on {addr}: {e}"))
        }
    })?;
    let glb = std::fs::read_dir(&args.dir)
        .ok()
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".baked.glb"))
        .min();
    let probes = if args.dir.join("probes.json").is_file() {
        "&probes=/bake/probes.json"
    } else {
        ""
    };
    match &glb {
        Some(g) => println!("radbake viewer: http://{addr}/?url=/bake/{g}{probes}"),
        None => println!(
            "radbake viewer: http://{addr}/ ({} holds no .baked.glb; drop one on the page)",
            args.dir.display()
        ),
    }
    serve(listener, &args.dir, args.requests).map_err(|e| (3, format!("serving {addr}: {e}")))
}

/// Threads of the runtime that answers requests.
const WORKERS: usize = 4;

/// Answers requests on `listener` until `limit` requests have been
/// answered (if given; the connections open then are closed once their
/// requests in flight are answered) or the listener fails.
///
/// Every connection is its own task on a multi-threaded tokio runtime
/// (hyper's HTTP/1.1), so a browser's keep-alive connections, however
/// many and however long idle, never keep another connection waiting.
/// `tiny_http` 0.12, used before, handled each connection on a thread of
/// its pool for the connection's whole life, and its pool could queue a
/// new connection behind busy ones: when several connections arrived
/// together, each was queued while the pool's count of idle threads was
/// stale, one idle thread took the first, and the rest waited until some
/// keep-alive connection closed. A page's module loads stalled that way
/// (2 of 9 runs of the browser tests in CI); 8
/// simultaneous keep-alive connections with both cores busy were left
/// unanswered in 3 of 10 rounds.
fn serve(listener: std::net::TcpListener, dir: &Path, limit: Option<u64>) -> std::io::Result<()> {
    use hyper_util::server::graceful::GracefulShutdown;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;
    listener.set_nonblocking(true)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(WORKERS)
        .enable_io()
        .build()?;
    let dir: Arc<Path> = dir.into();
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::from_std(listener)?;
        let graceful = GracefulShutdown::new();
        let served = Arc::new(AtomicU64::new(0));
        let done = Arc::new(tokio::sync::Notify::new());
        loop {
            let (stream, _) = tokio::select! {
                accepted = listener.accept() => accepted?,
                () = done.notified() => break,
            };
            let (dir, served, done) = (dir.clone(), served.clone(), done.clone());
            let service = hyper::service::service_fn(move |request: hyper::Request<_>| {
                let response = respond(&dir, request.uri().path());
                if limit == Some(served.fetch_add(1, Ordering::SeqCst) + 1) {
                    done.notify_one();
                }
                std::future::ready(Ok::<_, std::convert::Infallible>(response))
            });
            let connection = hyper::server::conn::http1::Builder::new()
                .serve_connection(hyper_util::rt::TokioIo::new(stream), service);
            // A client that goes away ends its connection; nothing to report.
            tokio::spawn(graceful.watch(connection));
        }
        graceful.shutdown().await;
        Ok(())
    })
}

/// The response to a GET of `path`: the file with its type, or 404.
fn respond(dir: &Path, path: &str) -> hyper::Response<http_body_util::Full<hyper::body::Bytes>> {
    use http_body_util::Full;
    let response = match resolve(dir, path) {
        Some((bytes, m)) => hyper::Response::builder()
            .header(hyper::header::CONTENT_TYPE, m)
            .body(Full::new(bytes.into())),
        None => hyper::Response::builder()
            .status(hyper::StatusCode::NOT_FOUND)
            .body(Full::new(hyper::body::Bytes::from_static(b"not found"))),
    };
    response.expect("a status and a known header make a valid response")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_names_in_the_bake_folder_are_served() {
        let dir = std::env::temp_dir().join(format!("radbake-serve-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.baked.glb"), b"glb").unwrap();
        assert_eq!(resolve(&dir, "/bake/a.baked.glb?x=1").unwrap().0, b"glb");
        assert_eq!(
            resolve(&dir, "/bake/a.baked.glb").unwrap().1,
            "model/gltf-binary"
        );
        for bad in [
            "/bake/../etc/passwd",
            "/bake/..",
            "/bake/",
            "/bake/sub/a.glb",
            "/bake/%2e%2e",
            "/etc/passwd",
        ] {
            assert!(resolve(&dir, bad).is_none(), "{bad}");
        }
        assert!(resolve(&dir, "/vendor/three/build/three.module.js").is_some());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A client that stops reading a large response does not hold up
    /// another connection's request (a single writer thread would wait on
    /// it forever), and `--requests` ends the server.
    #[test]
    fn a_stalled_reader_does_not_block_other_requests() {
        use std::io::{Read as _, Write as _};
        let dir = std::env::temp_dir().join(format!("radbake-serve-stall-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Far more than the loopback socket buffers hold unread.
        std::fs::write(dir.join("big.bin"), vec![7u8; 64 << 20]).unwrap();
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let served = {
            let dir = dir.clone();
            std::thread::spawn(move || serve(listener, &dir, Some(2)).unwrap())
        };
        let mut stalled = std::net::TcpStream::connect(addr).unwrap();
        write!(stalled, "GET /bake/big.bin HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
        // Wait until the big response has started (its worker is now stuck
        // writing), then ask for the page on a second connection.
        let mut first = [0u8; 12];
        stalled.read_exact(&mut first).unwrap();
        assert_eq!(&first, b"HTTP/1.1 200");
        let mut page = std::net::TcpStream::connect(addr).unwrap();
        page.set_read_timeout(Some(std::time::Duration::from_secs(20)))
            .unwrap();
        write!(
            page,
            "GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut reply = Vec::new();
        page.read_to_end(&mut reply)
            .expect("the page was not served");
        assert!(reply.starts_with(b"HTTP/1.1 200"));
        assert!(String::from_utf8_lossy(&reply).contains("<html"));
        drop(stalled);
        served.join().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Connections that arrive together are all answered, and stay open
    /// (keep-alive) without holding up the next ones: 10 rounds of 8
    /// simultaneous keep-alive connections, with both cores kept busy
    /// meanwhile (tiny_http's pool left some of them unanswered in 3 of 10
    /// such rounds; without the load, in none of 6).
    #[test]
    fn simultaneous_keep_alive_connections_are_all_answered() {
        use std::io::{Read as _, Write as _};
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::sync::Arc;
        let dir = std::env::temp_dir().join(format!("radbake-serve-burst-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (rounds, at_once) = (10, 8);
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let served = {
            let dir = dir.clone();
            std::thread::spawn(move || serve(listener, &dir, Some(rounds * at_once)).unwrap())
        };
        let busy = Arc::new(AtomicBool::new(true));
        let spinners: Vec<_> = (0..2)
            .map(|_| {
                let busy = busy.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while busy.load(Ordering::Relaxed) {
                        x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(1));
                    }
                })
            })
            .collect();
        for round in 0..rounds {
            let mut open: Vec<_> = (0..at_once)
                .map(|_| std::net::TcpStream::connect(addr).unwrap())
                .collect();
            for c in &mut open {
                write!(c, "GET /viewer.js HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
            }
            for (k, c) in open.iter_mut().enumerate() {
                c.set_read_timeout(Some(std::time::Duration::from_secs(20)))
                    .unwrap();
                let mut head = [0u8; 12];
                c.read_exact(&mut head)
                    .unwrap_or_else(|e| panic!("round {round}: connection {k} unanswered: {e}"));
                assert_eq!(&head, b"HTTP/1.1 200");
            }
        }
        busy.store(false, Ordering::Relaxed);
        spinners.into_iter().for_each(|s| s.join().unwrap());
        served.join().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
