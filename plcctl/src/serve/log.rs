//! The access and action log: one line per request (who: the peer address; what: the
//! method and path, never the query, which may carry the token; the result: the status
//! and, for an action, the PLC's answer), to stderr and, with `--log FILE`, appended to
//! that file.

use std::fs::File;
use std::io::Write as _;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Mutex;

/// Where the lines go.
pub struct Log {
    file: Option<Mutex<File>>,
}

impl Log {
    /// Stderr, and `file` appended to when given (opened now: a bad path fails before
    /// anything is served).
    pub fn open(file: Option<&Path>) -> std::io::Result<Log> {
        let file = match file {
            Some(p) => Some(Mutex::new(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)?,
            )),
            None => None,
        };
        Ok(Log { file })
    }

    /// `<UTC time> <peer> <what>` on one line (control characters in `what` escaped: a
    /// header value cannot forge a line).
    pub fn line(&self, peer: Option<SocketAddr>, what: &str) {
        let peer = peer.map_or_else(|| "-".to_string(), |p| p.to_string());
        let what: String = what
            .chars()
            .flat_map(|c| {
                let esc = c.is_control().then(|| c.escape_default());
                esc.into_iter()
                    .flatten()
                    .chain((!c.is_control()).then_some(c))
            })
            .collect();
        let line = format!(
            "{} {peer} {what}\n",
            chrono::Utc::now().format("%Y-%m-%dT%H:%M:%S%.3fZ")
        );
        eprint!("{line}");
        if let Some(f) = &self.file {
            let mut f = f.lock().unwrap_or_else(|p| p.into_inner());
            let _ = f.write_all(line.as_bytes());
            let _ = f.flush();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_appended_with_the_peer_and_no_forged_lines() {
        let dir = std::env::temp_dir().join(format!("plcctl-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("access.log");
        std::fs::write(&p, "earlier\n").unwrap();
        let log = Log::open(Some(&p)).unwrap();
        let peer: SocketAddr = "127.0.0.1:5555".parse().unwrap();
        log.line(Some(peer), "POST /api/stop 200 ok");
        log.line(Some(peer), "GET /x\nfake line");
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        assert_eq!(lines[0], "earlier");
        assert!(
            lines[1].ends_with(" 127.0.0.1:5555 POST /api/stop 200 ok"),
            "{text}"
        );
        assert!(lines[2].ends_with("GET /x\\nfake line"), "{text}");
    }
}
