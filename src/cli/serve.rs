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
    let server = tiny_http::Server::http(&addr).map_err(|e| {
        let taken = e
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::AddrInUse);
        if taken {
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
    answer(&server, &args.dir, args.requests);
    Ok(())
}

/// Worker threads answering requests: a browser fetches the page's modules
/// over several connections at once, and one slow reader (its data pipe
/// full until another module arrives) must not hold up the rest, as it can
/// with a single thread writing one response at a time.
const WORKERS: usize = 4;

/// Answers requests on [`WORKERS`] threads until `limit` requests have been
/// served (if given) or the listener fails.
fn answer(server: &tiny_http::Server, dir: &Path, limit: Option<u64>) {
    let served = std::sync::atomic::AtomicU64::new(0);
    let stop_all = || (0..WORKERS).for_each(|_| server.unblock());
    std::thread::scope(|scope| {
        for _ in 0..WORKERS {
            scope.spawn(|| {
                // `recv` fails when the listener fails or when unblocked;
                // either way every worker stops.
                loop {
                    let Ok(request) = server.recv() else {
                        stop_all();
                        break;
                    };
                    let response = match resolve(dir, request.url()) {
                        Some((bytes, m)) => {
                            let header = tiny_http::Header::from_bytes("Content-Type", m)
                                .expect("valid header");
                            tiny_http::Response::from_data(bytes).with_header(header)
                        }
                        None => tiny_http::Response::from_data(b"not found".to_vec())
                            .with_status_code(404),
                    };
                    let _ = request.respond(response);
                    let n = served.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
                    if limit == Some(n) {
                        stop_all();
                    }
                }
            });
        }
    });
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
        let server = tiny_http::Server::http("127.0.0.1:0").unwrap();
        let addr = server.server_addr().to_ip().unwrap();
        let served = {
            let dir = dir.clone();
            std::thread::spawn(move || answer(&server, &dir, Some(2)))
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
}
