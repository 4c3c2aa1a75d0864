//! Who may talk to the debugger: the `Host` allow-list (against DNS rebinding) and the
//! same-origin rule for anything that changes state or starts work (against cross-site request
//! forgery).

use std::net::{IpAddr, SocketAddr};

use axum::http::{header, HeaderMap, Method};

/// The `Host` values the debugger answers to.
///
/// A page on another site can make a browser send requests here only under a name it
/// controls (DNS rebinding: `evil.example` resolving to this machine), so names are allowed
/// only from a list: `localhost` and what the user named (`--host`, `--allow-host`). An IP
/// address is not a name anyone can rebind, so one is allowed when the server listens on it:
/// the bound address, any loopback address when bound to loopback, and any address when bound
/// to all interfaces.
#[derive(Debug, Clone)]
pub struct HostPolicy {
    addr: SocketAddr,
    names: Vec<String>,
}

impl HostPolicy {
    /// The policy for a server bound to `addr`, answering also to `names` (case-insensitive).
    pub fn new(addr: SocketAddr, names: &[String]) -> Self {
        let mut all = vec!["localhost".to_string()];
        all.extend(names.iter().map(|n| normalise_name(n)));
        all.sort();
        all.dedup();
        Self { addr, names: all }
    }

    /// The names allowed besides IP addresses, sorted.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether a request with this `Host` header value is answered.
    pub fn allows(&self, host: &str) -> bool {
        let Some((name, port)) = split_host(host) else {
            return false;
        };
        // A browser leaves out the port only when it is the scheme's default.
        if port.unwrap_or(80) != self.addr.port() {
            return false;
        }
        let bound = self.addr.ip();
        match name.trim_start_matches('[').trim_end_matches(']').parse::<IpAddr>() {
            Ok(ip) => bound.is_unspecified() || ip == bound || (ip.is_loopback() && bound.is_loopback()),
            Err(_) => {
                let name = normalise_name(name);
                self.names.contains(&name)
            }
        }
    }
}

/// Lower case, without a trailing dot (`Localhost.` is `localhost`).
fn normalise_name(n: &str) -> String {
    n.trim().trim_end_matches('.').to_ascii_lowercase()
}

/// `name[:port]` or `[v6][:port]`; `None` when malformed.
fn split_host(host: &str) -> Option<(&str, Option<u16>)> {
    if host.is_empty() || host.contains(['/', '@', ' ', '\\']) {
        return None;
    }
    let (name, port) = if host.starts_with('[') {
        let end = host.find(']')?;
        let rest = &host[end + 1..];
        let port = match rest.strip_prefix(':') {
            Some(p) => Some(p),
            None if rest.is_empty() => None,
            None => return None,
        };
        (&host[..=end], port)
    } else {
        match host.rsplit_once(':') {
            Some((n, p)) => (n, Some(p)),
            None => (host, None),
        }
    };
    let port = match port {
        Some(p) => Some(p.parse().ok()?),
        None => None,
    };
    (!name.is_empty()).then_some((name, port))
}

/// Why a request must be refused as coming from another site, or `None` when it may be
/// answered. `host` is the request's (already allowed) `Host` header.
///
/// The UI's own files may be opened from anywhere (a link, a bookmark). Every `/api/`
/// request, and every request that is not `GET`/`HEAD`, must come from the debugger's own
/// page: a browser marks requests from other pages with `Origin` (every cross-origin `POST`)
/// and `Sec-Fetch-Site` (every request, in current browsers), and the debugger refuses any
/// that name another origin or site, `same-site` included (another port on this machine is
/// the same site). Clients that send neither (curl, scripts, old browsers) are not browsers
/// acting for another page, or are stopped by the content types the `POST` endpoints require,
/// which a page on another origin cannot send without a preflight the debugger never grants.
pub fn cross_site_refusal(method: &Method, path: &str, headers: &HeaderMap, host: &str) -> Option<String> {
    let safe = *method == Method::GET || *method == Method::HEAD;
    if safe && !path.starts_with("/api/") {
        return None;
    }
    if let Some(site) = headers.get("sec-fetch-site") {
        let site = site.to_str().unwrap_or("?");
        // `none`: the user typed the address or followed a bookmark.
        let ok = site == "same-origin" || (safe && site == "none");
        if !ok {
            return Some(format!(
                "refused: the browser says this request comes from another page (Sec-Fetch-Site: {site}); only the debugger's own page may use its API"
            ));
        }
    }
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("?");
        if !origin.eq_ignore_ascii_case(&format!("http://{host}")) {
            return Some(format!(
                "refused: this request comes from a page on another origin ({origin}); only the debugger's own page at http://{host} may use its API"
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy(addr: &str, names: &[&str]) -> HostPolicy {
        let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        HostPolicy::new(addr.parse().unwrap(), &names)
    }

    #[test]
    fn loopback_answers_its_own_names_only() {
        let p = policy("127.0.0.1:8123", &[]);
        for ok in ["127.0.0.1:8123", "localhost:8123", "LOCALHOST.:8123", "[::1]:8123"] {
            assert!(p.allows(ok), "{ok}");
        }
        for bad in [
            "evil.example:8123",
            "127.0.0.1:8124",
            "127.0.0.1",
            "192.168.1.5:8123",
            "",
            "127.0.0.1:8123@evil.example",
            "localhost:8123:8123",
            "[::1]x:8123",
        ] {
            assert!(!p.allows(bad), "{bad}");
        }
    }

    #[test]
    fn all_interfaces_answer_addresses_and_listed_names() {
        let p = policy("0.0.0.0:8123", &["Lab-PC.local"]);
        for ok in [
            "192.168.1.5:8123",
            "10.0.0.2:8123",
            "127.0.0.1:8123",
            "localhost:8123",
            "lab-pc.local:8123",
        ] {
            assert!(p.allows(ok), "{ok}");
        }
        // A rebinding name is still refused: the guard is not off.
        for bad in ["evil.example:8123", "lab-pc.local.evil.example:8123", "192.168.1.5:80"] {
            assert!(!p.allows(bad), "{bad}");
        }
        assert_eq!(p.names(), ["lab-pc.local", "localhost"]);
        let p = policy("192.168.1.5:80", &[]);
        assert!(p.allows("192.168.1.5") && p.allows("192.168.1.5:80") && !p.allows("192.168.1.6"));
    }

    #[test]
    fn only_the_own_page_may_post_or_use_the_api() {
        let host = "127.0.0.1:8123";
        let h = |pairs: &[(&'static str, &'static str)]| {
            let mut m = HeaderMap::new();
            for (k, v) in pairs {
                m.insert(*k, v.parse().unwrap());
            }
            m
        };
        let post = Method::POST;
        let get = Method::GET;
        assert!(cross_site_refusal(&post, "/api/settings", &h(&[]), host).is_none());
        assert!(cross_site_refusal(&post, "/api/settings", &h(&[("origin", "http://127.0.0.1:8123")]), host).is_none());
        assert!(cross_site_refusal(&post, "/api/settings", &h(&[("sec-fetch-site", "same-origin")]), host).is_none());
        for bad in [
            h(&[("origin", "http://evil.example")]),
            h(&[("origin", "http://127.0.0.1:8124")]),
            h(&[("origin", "null")]),
            h(&[("sec-fetch-site", "cross-site")]),
            h(&[("sec-fetch-site", "same-site")]),
            h(&[("sec-fetch-site", "none")]),
        ] {
            assert!(
                cross_site_refusal(&post, "/api/settings", &bad, host).is_some(),
                "{bad:?}"
            );
            // A POST to a page route is refused the same way.
            assert!(cross_site_refusal(&post, "/", &bad, host).is_some(), "{bad:?}");
        }
        assert!(cross_site_refusal(&get, "/api/view", &h(&[("sec-fetch-site", "none")]), host).is_none());
        assert!(cross_site_refusal(&get, "/api/view", &h(&[("sec-fetch-site", "cross-site")]), host).is_some());
        assert!(cross_site_refusal(&get, "/", &h(&[("sec-fetch-site", "cross-site")]), host).is_none());
    }
}
