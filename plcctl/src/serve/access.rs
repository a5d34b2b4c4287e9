//! Who may use the server (service.md 14): on a loopback bind everybody on the machine
//! (the machine's user); on any other bind only requests carrying the token, as
//! `?token=` (the page's URL, once), as the cookie that URL sets, or as
//! `Authorization: Bearer`.

use std::net::SocketAddr;

/// The cookie that carries the token after the first visit.
pub const COOKIE: &str = "plcctl_token";

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

/// `key`'s value in a query string (percent-decoding is not needed: tokens are hex).
pub fn query_value(query: &str, key: &str) -> Option<String> {
    query
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == key)
        .map(|(_, v)| v.to_string())
}

/// Compares without stopping at the first difference.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// 128 random bits as 32 hex digits, from the operating system's random source (never
/// a made-up fallback: a guessable token is worse than none).
pub fn random_token() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
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
        let other = random_token().unwrap();
        assert_ne!(t, other, "random tokens differ");
        let a = Access::Token(t.clone());
        assert!(!a.allows(None, &[]));
        assert!(!a.allows(Some("token=wrong"), &[]));
        assert!(a.allows(Some(&format!("s=60&token={t}")), &[]));
        assert!(a.allows(None, &[h("Cookie", &format!("x=1; {COOKIE}={t}"))]));
        assert!(a.allows(None, &[h("authorization", &format!("Bearer {t}"))]));
        assert!(!a.allows(None, &[h("Cookie", &format!("{COOKIE}={other}"))]));
        // A given token applies on loopback too.
        assert_eq!(
            Access::for_bind(&lo, Some("abc".into())).unwrap(),
            Access::Token("abc".into())
        );
    }
}
