//! A small HTTP/1.1 server on std (one request per connection: `Connection: close`), enough
//! for one page, a JSON API and a Server-Sent Events stream. No crate: the routes are few,
//! the stream needs a connection held open and written to at 10 Hz (which a
//! request/response server makes awkward), and the request reader is about 100 lines
//! with tests. It never holds more of a request than its limits: every line is read
//! through [`Read::take`] with what is left of [`MAX_LINE`] and [`MAX_HEAD`], and the
//! caller gives the whole head one deadline ([`Deadline`]).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// Longest request line or header line (the longest real one is a `Cookie` or a
/// `User-Agent` of a few hundred bytes).
pub const MAX_LINE: usize = 4 * 1024;
/// Longest request head (request line and headers) and body (the POSTs carry `{}`).
pub const MAX_HEAD: usize = 16 * 1024;
pub const MAX_BODY: usize = 16 * 1024;
/// Most header lines.
const MAX_HEADERS: usize = 64;

/// A parsed request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    pub method: String,
    pub path: String,
    pub query: Option<String>,
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
}

impl Request {
    /// The first header `name` (case-insensitive).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// How many headers `name` there are (a second `Host` or `Origin` is refused).
    pub fn count(&self, name: &str) -> usize {
        self.headers
            .iter()
            .filter(|(k, _)| k.eq_ignore_ascii_case(name))
            .count()
    }
}

/// Why a request was not read; each has its status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadRequest {
    /// Not HTTP/1.x, a line without `:`, a bad `Content-Length`, or the client closed.
    Malformed,
    /// The request line is longer than [`MAX_LINE`].
    UriTooLong,
    /// A header line longer than [`MAX_LINE`], or the head longer than [`MAX_HEAD`], or
    /// more than 64 headers.
    HeadTooLarge,
    /// A body longer than [`MAX_BODY`].
    BodyTooLarge,
    /// The head (and body) did not arrive before the deadline.
    Timeout,
}

impl BadRequest {
    pub fn status(self) -> (u16, &'static str) {
        match self {
            BadRequest::Malformed => (400, "bad request"),
            BadRequest::UriTooLong => (414, "request line too long"),
            BadRequest::HeadTooLarge => (431, "request header fields too large"),
            BadRequest::BodyTooLarge => (413, "request body too large"),
            BadRequest::Timeout => (408, "request not complete in time"),
        }
    }
}

fn io_error(e: std::io::Error) -> BadRequest {
    match e.kind() {
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => BadRequest::Timeout,
        _ => BadRequest::Malformed,
    }
}

/// One line of at most `limit` bytes (its `\n` included): more is `too_long`, without
/// reading past `limit + 1` bytes.
fn read_line(
    r: &mut impl BufRead,
    limit: usize,
    too_long: BadRequest,
) -> Result<String, BadRequest> {
    let mut buf = Vec::new();
    let n = r
        .take(limit as u64 + 1)
        .read_until(b'\n', &mut buf)
        .map_err(io_error)?;
    if buf.last() != Some(&b'\n') {
        return Err(if n > limit {
            too_long
        } else {
            BadRequest::Malformed
        });
    }
    if n > limit {
        return Err(too_long);
    }
    let line = String::from_utf8(buf).map_err(|_| BadRequest::Malformed)?;
    Ok(line.trim_end_matches(['\r', '\n']).to_string())
}

/// Reads one request.
pub fn read_request(stream: impl Read) -> Result<Request, BadRequest> {
    let mut r = BufReader::with_capacity(1024, stream);
    let line = read_line(&mut r, MAX_LINE, BadRequest::UriTooLong)?;
    let mut head = line.len() + 2;
    let mut parts = line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(BadRequest::Malformed);
    };
    if !version.starts_with("HTTP/1.") || method.is_empty() || !target.starts_with('/') {
        return Err(BadRequest::Malformed);
    }
    let (method, target) = (method.to_string(), target.to_string());
    let mut headers = Vec::new();
    loop {
        let left = MAX_HEAD.saturating_sub(head);
        let l = read_line(&mut r, left.min(MAX_LINE), BadRequest::HeadTooLarge)?;
        head += l.len() + 2;
        if l.is_empty() {
            break;
        }
        if headers.len() == MAX_HEADERS {
            return Err(BadRequest::HeadTooLarge);
        }
        let (k, v) = l.split_once(':').ok_or(BadRequest::Malformed)?;
        headers.push((k.trim().to_string(), v.trim().to_string()));
    }
    let lengths: Vec<&String> = headers
        .iter()
        .filter(|(k, _)| k.eq_ignore_ascii_case("content-length"))
        .map(|(_, v)| v)
        .collect();
    let len: usize = match lengths.as_slice() {
        [] => 0,
        [v] => v.parse().map_err(|_| BadRequest::Malformed)?,
        _ => return Err(BadRequest::Malformed),
    };
    if headers
        .iter()
        .any(|(k, _)| k.eq_ignore_ascii_case("transfer-encoding"))
    {
        return Err(BadRequest::Malformed);
    }
    if len > MAX_BODY {
        return Err(BadRequest::BodyTooLarge);
    }
    let mut body = vec![0u8; len];
    r.read_exact(&mut body).map_err(io_error)?;
    let (path, query) = match target.split_once('?') {
        Some((p, q)) => (p.to_string(), Some(q.to_string())),
        None => (target, None),
    };
    Ok(Request {
        method,
        path,
        query,
        headers,
        body,
    })
}

/// A reader of a socket that fails once `deadline` has passed, however slowly the bytes
/// trickle in (each read waits at most for what is left).
pub struct Deadline<'a> {
    pub stream: &'a TcpStream,
    pub deadline: Instant,
}

impl Read for Deadline<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        self.stream
            .set_read_timeout(Some(left.max(Duration::from_millis(1))))?;
        self.stream.read(buf)
    }
}

/// The headers every response carries: no caching, no MIME sniffing, never framed
/// (clickjacking: `X-Frame-Options` for old browsers, CSP `frame-ancestors` for new
/// ones), nothing loaded from anywhere but this server, no `Referer` (a URL may carry
/// the token once), no CORS header ever.
pub const SECURITY_HEADERS: &str = "Cache-Control: no-store\r\n\
X-Content-Type-Options: nosniff\r\n\
X-Frame-Options: DENY\r\n\
Content-Security-Policy: default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'\r\n\
Referrer-Policy: no-referrer\r\n\
Cross-Origin-Opener-Policy: same-origin\r\n\
Cross-Origin-Resource-Policy: same-origin\r\n";

/// A whole response.
pub struct Response {
    pub status: u16,
    pub content_type: &'static str,
    pub headers: Vec<(&'static str, String)>,
    pub body: Vec<u8>,
}

impl Response {
    pub fn new(status: u16, content_type: &'static str, body: impl Into<Vec<u8>>) -> Self {
        Response {
            status,
            content_type,
            headers: Vec::new(),
            body: body.into(),
        }
    }

    pub fn json(status: u16, v: &serde_json::Value) -> Self {
        Response::new(status, "application/json", v.to_string())
    }

    /// `{"error": msg}` with `status`.
    pub fn error(status: u16, msg: &str) -> Self {
        Response::json(status, &serde_json::json!({ "error": msg }))
    }

    pub fn with_header(mut self, name: &'static str, value: String) -> Self {
        self.headers.push((name, value));
        self
    }

    pub fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        let mut head = format!(
            "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\n{SECURITY_HEADERS}Connection: close\r\n",
            self.status,
            reason(self.status),
            self.content_type,
            self.body.len()
        );
        for (k, v) in &self.headers {
            head += &format!("{k}: {v}\r\n");
        }
        head += "\r\n";
        w.write_all(head.as_bytes())?;
        w.write_all(&self.body)?;
        w.flush()
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        413 => "Content Too Large",
        414 => "URI Too Long",
        415 => "Unsupported Media Type",
        421 => "Misdirected Request",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Status",
    }
}

/// Starts a Server-Sent Events response.
pub fn start_events(s: &mut TcpStream) -> std::io::Result<()> {
    let head = format!(
        "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\n{SECURITY_HEADERS}Connection: close\r\n\r\n"
    );
    s.write_all(head.as_bytes())?;
    s.flush()
}

/// One event of the stream.
pub fn event(name: &str, data: &str) -> String {
    format!("event: {name}\ndata: {data}\n\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_post_with_its_body_and_query() {
        let raw = b"POST /api/stop?x=1 HTTP/1.1\r\nHost: a\r\nContent-Type: application/json\r\nContent-Length: 2\r\n\r\n{}";
        let r = read_request(&raw[..]).unwrap();
        assert_eq!(r.method, "POST");
        assert_eq!(r.path, "/api/stop");
        assert_eq!(r.query.as_deref(), Some("x=1"));
        assert_eq!(r.header("content-type"), Some("application/json"));
        assert_eq!(r.body, b"{}");
    }

    #[test]
    fn refuses_garbage_and_oversized_requests() {
        let bad = |raw: &[u8]| read_request(raw).unwrap_err();
        assert_eq!(bad(b"hello\r\n\r\n"), BadRequest::Malformed);
        assert_eq!(
            bad(b"GET / HTTP/1.1\r\nno colon\r\n\r\n"),
            BadRequest::Malformed
        );
        let big = format!(
            "POST / HTTP/1.1\r\nContent-Length: {}\r\n\r\n",
            MAX_BODY + 1
        );
        assert_eq!(bad(big.as_bytes()), BadRequest::BodyTooLarge);
        assert_eq!(bad(b"GET / HTTP/1.1\r\nHost: a\r\n"), BadRequest::Malformed);
        assert_eq!(
            bad(b"POST / HTTP/1.1\r\nContent-Length: 1\r\nContent-Length: 1\r\n\r\nx"),
            BadRequest::Malformed
        );
    }

    /// A reader that counts what is taken from it: an endless line is never read past
    /// the limit.
    struct Endless {
        given: usize,
        head: &'static [u8],
    }

    impl Read for Endless {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len();
            for (i, b) in buf.iter_mut().enumerate() {
                *b = self.head.get(self.given + i).copied().unwrap_or(b'a');
            }
            self.given += n;
            Ok(n)
        }
    }

    #[test]
    fn an_endless_line_is_refused_after_the_limit_not_at_its_end() {
        for (head, want) in [
            (&b""[..], BadRequest::UriTooLong),
            (&b"GET / HTTP/1.1\r\nX: "[..], BadRequest::HeadTooLarge),
        ] {
            let mut r = Endless { given: 0, head };
            assert_eq!(read_request(&mut r).unwrap_err(), want);
            // What the BufReader took: the limit plus at most one buffer.
            assert!(r.given <= MAX_LINE + 2048 + head.len(), "{}", r.given);
        }
        // Many short lines: the head's limit.
        let mut many = b"GET / HTTP/1.1\r\n".to_vec();
        for i in 0..2000 {
            many.extend_from_slice(format!("X-{i}: {}\r\n", "v".repeat(20)).as_bytes());
        }
        assert_eq!(
            read_request(&many[..]).unwrap_err(),
            BadRequest::HeadTooLarge
        );
    }

    #[test]
    fn a_response_has_its_length_the_frame_refusal_and_no_cors_header() {
        let mut out = Vec::new();
        Response::error(415, "x").write_to(&mut out).unwrap();
        let t = String::from_utf8(out).unwrap();
        assert!(t.starts_with("HTTP/1.1 415 Unsupported Media Type\r\n"));
        assert!(t.contains("Content-Length: 13\r\n"));
        assert!(t.contains("X-Frame-Options: DENY\r\n"));
        assert!(t.contains("frame-ancestors 'none'"));
        assert!(!t.to_ascii_lowercase().contains("access-control"));
    }
}
