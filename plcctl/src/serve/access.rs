//! Who may use the server (service.md 14, threat model in `plcctl/docs/serve.md`).
//!
//! - [`Hosts`]: the `Host` header must name this server (the bind address, `localhost`,
//!   `127.0.0.1`, `[::1]`, the address the client connected to, or a `--host` name): a
//!   page on another name that resolves to this machine (DNS rebinding) is refused.
//! - Same origin for anything but GET: a browser's `Origin` (and `Sec-Fetch-Site`) must
//!   say the request comes from this server's own page (cross-site request forgery).
//! - [`Access`]: on a loopback bind everybody on the machine (the machine's user); on any
//!   other bind, or with a token given, only requests carrying the token, as `?token=`
//!   (the page's URL, once), as the cookie that URL sets, or as `Authorization: Bearer`.

use std::net::{IpAddr, SocketAddr};

/// The cookie that carries the token after the first visit.
pub const COOKIE: &str = "plcctl_token";
/// The shortest token taken from the user: 32 characters (32 hex digits are 128 bits).
pub const MIN_TOKEN_CHARS: usize = 32;

/// The access rule of one `serve`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Access {
    /// Loopback bind: no token.
    Open,
    /// Any other bind: this token.
    Token(String),
}

impl Access {
    /// The rule for `bind`: a token (`given`, else a random one) unless it is loopback.
    /// Fails only when the operating system has no random source.
    pub fn for_bind(bind: &SocketAddr, given: Option<String>) -> Result<Access, getrandom::Error> {
        Ok(match given {
            Some(t) => Access::Token(t),
            None if bind.ip().is_loopback() => Access::Open,
            None => Access::Token(random_token()?),
        })
    }

    /// Whether a request with this query string and these headers may pass.
    pub fn allows(&self, query: Option<&str>, headers: &[(String, String)]) -> bool {
        let Access::Token(token) = self else {
            return true;
        };
        let from_query = query.and_then(|q| query_value(q, "token"));
        let header = |name: &'static str| {
            headers
                .iter()
                .filter(move |(k, _)| k.eq_ignore_ascii_case(name))
                .map(|(_, v)| v.as_str())
        };
        let from_cookie = header("cookie").find_map(|c| {
            c.split(';')
                .filter_map(|kv| kv.trim().split_once('='))
                .find(|(k, _)| *k == COOKIE)
                .map(|(_, v)| v.to_string())
        });
        let from_bearer = header("authorization")
            .find_map(|v| v.strip_prefix("Bearer ").map(|t| t.trim().to_string()));
        [from_query, from_cookie, from_bearer]
            .into_iter()
            .flatten()
            .any(|t| same(&t, token))
    }
}

/// A token the user gives (`--token-file`, `PLCCTL_TOKEN`): at least
/// [`MIN_TOKEN_CHARS`] characters a URL carries as they are (letters, digits, `-._~`).
/// It travels in `?token=` once, so it must need no percent-encoding.
pub fn check_token(t: &str) -> Result<(), String> {
    if t.chars().count() < MIN_TOKEN_CHARS {
        return Err(format!(
            "the token has {} characters, at least {MIN_TOKEN_CHARS} are needed (128 bits: \
             `openssl rand -hex 16`, or give none off loopback and serve makes one)",
            t.chars().count()
        ));
    }
    if let Some(c) = t
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || "-._~".contains(*c)))
    {
        return Err(format!(
            "the token contains {c:?}: only letters, digits and -._~ are allowed"
        ));
    }
    Ok(())
}

/// `key`'s value in a query string (percent-decoding is not needed: tokens are
/// unreserved characters).
pub fn query_value(query: &str, key: &str) -> Option<String> {
    query
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == key)
        .map(|(_, v)| v.to_string())
}

/// Compares without stopping at the first difference (only the length shows in the
/// time; every byte of equal-length tokens is looked at).
fn same(a: &str, b: &str) -> bool {
    let diff = a
        .bytes()
        .zip(b.bytes())
        .fold(0u8, |acc, (x, y)| acc | std::hint::black_box(x ^ y));
    a.len() == b.len() && diff == 0
}

/// 128 random bits as 32 hex digits, from the operating system's random source (never
/// a made-up fallback: a guessable token is worse than none).
pub fn random_token() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The names this server answers to (`Host`), and its own origins.
#[derive(Debug, Clone)]
pub struct Hosts {
    /// Lower-case host names and address literals (IPv6 in brackets), without the port.
    names: Vec<String>,
    port: u16,
}

/// An address as it appears in a `Host` header (IPv6 in brackets).
fn literal(ip: IpAddr) -> String {
    match ip {
        IpAddr::V4(a) => a.to_string(),
        IpAddr::V6(a) => format!("[{a}]"),
    }
}

impl Hosts {
    /// `localhost`, `127.0.0.1`, `[::1]`, the bind address and the `--host` names, on
    /// the bound port.
    pub fn new(bind: &SocketAddr, extra: &[String]) -> Hosts {
        let mut names: Vec<String> = ["localhost", "127.0.0.1", "[::1]"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        if !bind.ip().is_unspecified() {
            names.push(literal(bind.ip()));
        }
        names.extend(
            extra
                .iter()
                .map(|n| n.trim_end_matches('.').to_ascii_lowercase()),
        );
        Hosts {
            names,
            port: bind.port(),
        }
    }

    /// Whether `host` (a `Host` header) names this server; `local` is the address the
    /// client connected to (an address literal involves no DNS, so it cannot be
    /// rebound: on a `0.0.0.0` bind the machine's own addresses are served).
    pub fn allows(&self, host: &str, local: IpAddr) -> bool {
        let host = host.to_ascii_lowercase();
        // `name[:port]`, the name an IPv6 literal in brackets.
        let (name, port) = match host.strip_prefix('[') {
            Some(rest) => match rest.split_once(']') {
                Some((addr, "")) => (format!("[{addr}]"), None),
                Some((addr, p)) => match p.strip_prefix(':') {
                    Some(p) => (format!("[{addr}]"), Some(p)),
                    None => return false,
                },
                None => return false,
            },
            None => match host.split_once(':') {
                Some((n, p)) => (n.to_string(), Some(p)),
                None => (host.clone(), None),
            },
        };
        let port_ok = match port {
            None => self.port == 80,
            Some(p) => p.parse::<u16>().is_ok_and(|p| p == self.port),
        };
        port_ok && (self.names.contains(&name) || name == literal(local))
    }
}

/// Whether a request that changes something comes from this server's own page: its
/// `Origin` (sent by every browser with a POST) is `http://` + its `Host` (already
/// checked by [`Hosts::allows`]), and its `Sec-Fetch-Site`, where the browser sends one,
/// is `same-origin`. Without either header the client is not a browser (curl, a
/// script): nothing cross-site to refuse.
pub fn same_origin(host: &str, origin: Option<&str>, fetch_site: Option<&str>) -> bool {
    let origin_ok = origin.is_none_or(|o| o.eq_ignore_ascii_case(&format!("http://{host}")));
    let site_ok = fetch_site.is_none_or(|s| s.eq_ignore_ascii_case("same-origin"));
    origin_ok && site_ok
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(k: &str, v: &str) -> (String, String) {
        (k.to_string(), v.to_string())
    }

    #[test]
    fn loopback_is_open_and_any_other_bind_needs_the_token() {
        let lo: SocketAddr = "127.0.0.1:0".parse().unwrap();
        let any: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        assert_eq!(Access::for_bind(&lo, None).unwrap(), Access::Open);
        assert!(Access::Open.allows(None, &[]));
        let Access::Token(t) = Access::for_bind(&any, None).unwrap() else {
            panic!("a token off loopback");
        };
        assert_eq!(t.len(), 32);
        assert!(t.chars().all(|c| c.is_ascii_hexdigit()));
        assert_eq!(check_token(&t), Ok(()));
        let other = random_token().unwrap();
        assert_ne!(t, other, "random tokens differ");
        let a = Access::Token(t.clone());
        assert!(!a.allows(None, &[]));
        assert!(!a.allows(Some("token=wrong"), &[]));
        assert!(!a.allows(Some("token="), &[]));
        assert!(!a.allows(Some(&format!("token={}", &t[..31])), &[]));
        assert!(a.allows(Some(&format!("s=60&token={t}")), &[]));
        assert!(a.allows(None, &[h("Cookie", &format!("x=1; {COOKIE}={t}"))]));
        assert!(a.allows(None, &[h("authorization", &format!("Bearer {t}"))]));
        assert!(!a.allows(None, &[h("Cookie", &format!("{COOKIE}={other}"))]));
    }

    #[test]
    fn short_or_odd_tokens_are_refused() {
        assert!(check_token("").is_err());
        assert!(check_token(&"a".repeat(31)).is_err());
        assert!(check_token(&format!("{}&x", "a".repeat(32))).is_err());
        assert!(check_token(&format!("{} ", "a".repeat(32))).is_err());
        assert_eq!(check_token(&"A-._~z9".repeat(5)), Ok(()));
    }

    #[test]
    fn only_this_servers_names_and_port_are_served() {
        let lo4: IpAddr = "127.0.0.1".parse().unwrap();
        let hosts = Hosts::new(&"127.0.0.1:8080".parse().unwrap(), &["plc.lan".into()]);
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST:8080",
            "[::1]:8080",
            "plc.lan:8080",
        ] {
            assert!(hosts.allows(ok, lo4), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "localhost.evil.example:8080",
            "127.0.0.1:8081",
            "127.0.0.1",
            "localhost",
            "127.0.0.1:8080:1",
            "[::1",
            "",
            "127.0.0.2:8080",
        ] {
            assert!(!hosts.allows(bad, lo4), "{bad}");
        }
        // A 0.0.0.0 bind: the address the client used, never a name it resolved.
        let any = Hosts::new(&"0.0.0.0:80".parse().unwrap(), &[]);
        let lan: IpAddr = "192.168.1.20".parse().unwrap();
        assert!(any.allows("192.168.1.20", lan));
        assert!(any.allows("192.168.1.20:80", lan));
        assert!(!any.allows("192.168.1.21", lan));
        assert!(!any.allows("rebind.example", lan));
        let v6 = Hosts::new(&"[::1]:9000".parse().unwrap(), &[]);
        assert!(v6.allows("[::1]:9000", "::1".parse().unwrap()));
    }

    #[test]
    fn a_post_from_another_origin_is_refused() {
        let host = "127.0.0.1:8080";
        assert!(same_origin(
            host,
            Some("http://127.0.0.1:8080"),
            Some("same-origin")
        ));
        assert!(same_origin(host, None, None), "curl");
        assert!(!same_origin(host, Some("http://evil.example"), None));
        assert!(!same_origin(host, Some("null"), None));
        assert!(!same_origin(host, Some("http://localhost:8080"), None));
        assert!(!same_origin(host, Some("https://127.0.0.1:8080"), None));
        assert!(!same_origin(host, None, Some("cross-site")));
        assert!(!same_origin(host, None, Some("same-site")));
    }
}
