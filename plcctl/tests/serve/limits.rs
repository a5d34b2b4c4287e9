//! What a request may be (docs/serve.md, threat model): every line capped while it is
//! read, one deadline for the whole head, a cap on connections, the token from a file
//! or the environment only. No PLC is needed: `serve` runs against a port that does not
//! exist (it keeps retrying it) and answers all the same.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::process::Command;
use std::time::Duration;

use super::{temp, Serve, PLCCTL};

/// A `serve` with no PLC behind it.
fn serve_without_plc(token: Option<&str>, extra: &[&str]) -> Serve {
    let port = temp("no-such-port");
    Serve::start_on(port.to_str().unwrap(), token, extra)
}

/// The status code of an HTTP answer read from `s` (30 s at most), or `None` when the
/// connection was reset or closed without one.
fn answer(s: &mut TcpStream) -> Option<u16> {
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut text = Vec::new();
    let _ = s.read_to_end(&mut text);
    let text = String::from_utf8_lossy(&text);
    text.strip_prefix("HTTP/1.1 ")?.get(..3)?.parse().ok()
}

/// serve's peak resident memory, KiB (Linux: `VmHWM` of /proc/PID/status).
fn peak_rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

#[test]
fn endless_lines_are_cut_while_reading_and_the_head_has_one_deadline() {
    let serve = serve_without_plc(None, &[]);
    let addr = serve.addr();
    // One header line of up to 256 MiB without its end: the server stops reading after
    // the limit and closes, so the writes fail long before (the socket buffers hold a
    // few MiB); its memory never grows by the line.
    let mut s = TcpStream::connect(&addr).unwrap();
    s.set_write_timeout(Some(Duration::from_secs(30))).unwrap();
    s.write_all(format!("GET / HTTP/1.1\r\nHost: {addr}\r\nX-Long: ").as_bytes())
        .unwrap();
    let chunk = vec![b'a'; 1 << 20];
    let mut sent_mib = 0;
    while sent_mib < 256 && s.write_all(&chunk).is_ok() {
        sent_mib += 1;
    }
    assert!(
        sent_mib < 64,
        "the server took {sent_mib} MiB of one header line"
    );
    drop(s);
    let peak_mib = peak_rss_kib(serve.pid()) / 1024;
    assert!(peak_mib < 64, "serve grew to {peak_mib} MiB");
    // The same with a request line.
    let mut s = TcpStream::connect(&addr).unwrap();
    s.set_write_timeout(Some(Duration::from_secs(30))).unwrap();
    s.write_all(b"GET /").unwrap();
    let mut sent_mib = 0;
    while sent_mib < 256 && s.write_all(&chunk).is_ok() {
        sent_mib += 1;
    }
    assert!(
        sent_mib < 64,
        "the server took {sent_mib} MiB of one request line"
    );
    drop(s);
    // A line over the limit that the client ends: the answer says which limit.
    for (head, code) in [
        (format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(5000)), 414),
        (
            format!(
                "GET / HTTP/1.1\r\nHost: {addr}\r\nX-Long: {}\r\n\r\n",
                "a".repeat(5000)
            ),
            431,
        ),
        (
            format!(
                "GET / HTTP/1.1\r\nHost: {addr}\r\n{}\r\n",
                "X-Many: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n"
                    .repeat(300)
            ),
            431,
        ),
        ("GET / HTTP/1.1\r\n\r\n".to_string(), 400),
        (
            format!("GET / HTTP/1.1\r\nHost: {addr}\r\nHost: {addr}\r\n\r\n"),
            400,
        ),
    ] {
        let mut s = TcpStream::connect(&addr).unwrap();
        s.write_all(head.as_bytes()).unwrap();
        s.shutdown(Shutdown::Write).unwrap();
        assert_eq!(answer(&mut s), Some(code), "{}", &head[..40]);
    }
    // A head trickled one byte every 200 ms (it would take 60 s): 408 at the head's
    // deadline, while the client is still sending.
    let mut s = TcpStream::connect(&addr).unwrap();
    let mut w = s.try_clone().unwrap();
    let head = format!(
        "GET / HTTP/1.1\r\nHost: {addr}\r\nX-Slow: {}\r\n\r\n",
        "a".repeat(300)
    );
    let trickle = std::thread::spawn(move || {
        for b in head.bytes() {
            if w.write_all(&[b]).is_err() {
                return false;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        true
    });
    assert_eq!(answer(&mut s), Some(408));
    drop(s);
    assert!(!trickle.join().unwrap(), "the whole head was taken");
    serve.wait_log(&["- 408"]);
    // Still serving.
    let (code, _, _) = serve.raw("GET", "/api/status", &[], "", false);
    assert_eq!(code, 200);
}

#[test]
fn connections_beyond_the_cap_get_503_and_the_cap_frees() {
    const CAP: usize = 32;
    let serve = serve_without_plc(None, &[]);
    let addr = serve.addr();
    // Event streams hold their connections open: CAP of them fill the server.
    let mut streams: Vec<TcpStream> = (0..CAP)
        .map(|_| {
            let mut s = TcpStream::connect(&addr).unwrap();
            write!(s, "GET /api/stream HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
            s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
            let mut buf = [0u8; 12];
            s.read_exact(&mut buf).unwrap();
            assert_eq!(&buf, b"HTTP/1.1 200");
            s
        })
        .collect();
    let (code, _, body) = serve.raw("GET", "/api/status", &[], "", false);
    assert_eq!(code, 503, "{body}");
    serve.wait_log(&["connection refused: 503"]);
    // One stream closed: its slot comes back (the server notices at its next write,
    // within a second).
    drop(streams.pop());
    let end = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        let (code, _, _) = serve.raw("GET", "/api/status", &[], "", false);
        if code == 200 {
            break;
        }
        assert!(std::time::Instant::now() < end, "the slot never came back");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn the_token_comes_from_a_file_or_the_environment_never_the_command_line() {
    let serve_cmd = |args: &[&str], env: Option<&str>| {
        let mut c = Command::new(PLCCTL);
        c.env("XDG_CACHE_HOME", temp("cache"))
            .env_remove("PLCCTL_TOKEN")
            .args(["--port", "/nonexistent", "serve", "--bind", "127.0.0.1:0"])
            .args(args);
        if let Some(t) = env {
            c.env("PLCCTL_TOKEN", t);
        }
        c.output().unwrap()
    };
    let long = "0123456789abcdef0123456789abcdef";
    for (args, env, says) in [
        (vec!["--token", long], None, "--token is refused"),
        (vec!["--token", ""], None, "--token is refused"),
        (vec![], Some(""), "PLCCTL_TOKEN: the token has 0 characters"),
        (vec![], Some("short"), "at least 32"),
        (vec![], Some(&format!("{long} x")[..]), "only letters"),
    ] {
        let o = serve_cmd(&args, env);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?} {env:?}: {err}");
        assert!(err.contains(says), "{args:?} {env:?}: {err}");
        assert!(o.stdout.is_empty(), "nothing served");
    }
    let short = temp("short-token");
    std::fs::write(&short, "abc\n").unwrap();
    let o = serve_cmd(&["--token-file", short.to_str().unwrap()], None);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("at least 32"));
    // A good token from a file: required on loopback too, compared whole.
    let serve = serve_without_plc(Some(long), &[]);
    let (code, _, _) = serve.raw("GET", "/api/status", &[], "", true);
    assert_eq!(code, 401);
    let (code, _, _) = serve.raw(
        "GET",
        "/api/status",
        &[("Authorization", &format!("Bearer {}", &long[..31]))],
        "",
        true,
    );
    assert_eq!(code, 401);
    let (code, _, _) = serve.raw("GET", "/api/status", &[], "", false);
    assert_eq!(code, 200);
}
