//! Who may call the API, from which web pages, and which client a request counts against.
//!
//! - Keys: with `MESHFIT_API_KEYS` (or a keys file) set, every `/v1` route needs
//!   `Authorization: Bearer <key>`; health, metrics, the spec and the page stay open. Keys are
//!   kept only as SHA-256 digests, and a client is named by a digest's first bytes.
//! - Origins: a browser sends `Origin` with every cross-origin POST, including the "simple"
//!   ones (`text/plain`, forms) that skip the CORS preflight. A request that changes state and
//!   names an origin other than the server's own or one in `MESHFIT_CORS_ORIGINS` is refused,
//!   so no web page can make a visitor's browser submit jobs. Listed origins also get CORS
//!   headers (tower-http's `CorsLayer`, added in `super::router`).
//! - Clients: the key's name, or without keys the peer's IP address; behind a proxy listed in
//!   `MESHFIT_TRUSTED_PROXIES`, the address its `Forwarded` (RFC 7239) or `X-Forwarded-For`
//!   header names. The registry gives each client at most its share of the workers and the
//!   queue.

use super::problem::ApiError;
use crate::config::ApiKeys;
use crate::jobs::Client;
use axum::extract::{ConnectInfo, Request, State};
use axum::http::{HeaderMap, Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use ipnet::IpNet;
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

/// What the access check needs, shared by every request.
#[derive(Clone, Debug, Default)]
pub struct Access {
    /// The API keys; empty for an open API.
    pub keys: ApiKeys,
    /// Origins (`scheme://host[:port]`) whose pages may call the API.
    pub origins: Arc<[String]>,
    /// Proxies whose forwarding headers name the client.
    pub trusted_proxies: Arc<[IpNet]>,
}

/// Authenticates `/v1` requests, refuses state changes from foreign origins, and tags each
/// request with its [`Client`].
pub async fn check(State(access): State<Arc<Access>>, mut req: Request, next: Next) -> Response {
    if !req.uri().path().starts_with("/v1/") {
        return next.run(req).await;
    }
    let changes_state = !matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    if changes_state && !origin_allowed(req.headers(), &access.origins) {
        return ApiError::CrossOrigin.into_response();
    }
    let client = if access.keys.is_empty() {
        let peer = req.extensions().get::<ConnectInfo<SocketAddr>>().map(|c| c.0.ip());
        let ip = peer.map(|peer| client_address(peer, req.headers(), &access.trusted_proxies));
        Client::from(ip.map_or_else(|| "addr:unknown".to_owned(), |ip| format!("addr:{ip}")))
    } else {
        let presented = bearer(req.headers());
        match presented.and_then(|key| access.keys.client_name(key)) {
            Some(name) => Client::from(name),
            None => return ApiError::Unauthorized { presented: presented.is_some() }.into_response(),
        }
    };
    req.extensions_mut().insert(client);
    next.run(req).await
}

/// The client's address: the peer's, unless the peer is a trusted proxy; then the last address
/// of the forwarding chain that is not a trusted proxy (each proxy appends the address it was
/// called from, so the addresses before the last untrusted one could have been written by the
/// client itself). `Forwarded` wins over `X-Forwarded-For`; a chain of trusted proxies only
/// gives its first, and no readable chain gives the peer.
fn client_address(peer: IpAddr, headers: &HeaderMap, trusted: &[IpNet]) -> IpAddr {
    let is_trusted = |ip: &IpAddr| trusted.iter().any(|net| net.contains(ip));
    if !is_trusted(&peer) {
        return peer;
    }
    let lines =
        |name| headers.get_all(name).iter().filter_map(|v| v.to_str().ok()).collect::<Vec<_>>().join(",");
    let forwarded = lines(header::FORWARDED);
    let chain: Vec<IpAddr> = if forwarded.is_empty() {
        lines(header::HeaderName::from_static("x-forwarded-for"))
            .split(',')
            .filter_map(node_address)
            .collect()
    } else {
        // `for=192.0.2.60;proto=http, for="[2001:db8::17]:4711"`: the `for` of each element.
        (forwarded.split(','))
            .filter_map(|element| {
                element.split(';').find_map(|pair| {
                    let (key, value) = pair.split_once('=')?;
                    key.trim().eq_ignore_ascii_case("for").then(|| node_address(value))?
                })
            })
            .collect()
    };
    chain.iter().rev().find(|ip| !is_trusted(ip)).or(chain.first()).copied().unwrap_or(peer)
}

/// An address as a forwarding header writes it: bare, quoted, in brackets, with a port.
fn node_address(node: &str) -> Option<IpAddr> {
    let node = node.trim().trim_matches('"');
    if let Ok(ip) = node.parse() {
        return Some(ip);
    }
    if let Some(bracketed) = node.strip_prefix('[') {
        return bracketed.split(']').next()?.parse().ok();
    }
    node.rsplit_once(':')?.0.parse().ok()
}

/// The token of an `Authorization: Bearer` header.
fn bearer(headers: &HeaderMap) -> Option<&str> {
    let value = headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, token) = value.split_once(' ')?;
    scheme.eq_ignore_ascii_case("bearer").then(|| token.trim())
}

/// No `Origin` (not a browser, or a same-origin GET), the server's own origin, or a listed
/// one.
fn origin_allowed(headers: &HeaderMap, allowed: &[String]) -> bool {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|o| o.to_str().ok()) else {
        return headers.get(header::ORIGIN).is_none();
    };
    let own = headers.get(header::HOST).and_then(|h| h.to_str().ok()).is_some_and(|host| {
        origin.strip_prefix("http://").or_else(|| origin.strip_prefix("https://")) == Some(host)
    });
    own || allowed.iter().any(|a| a == "*" || a.eq_ignore_ascii_case(origin))
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(pairs: &[(header::HeaderName, &str)]) -> HeaderMap {
        pairs.iter().map(|(k, v)| (k.clone(), HeaderValue::from_str(v).unwrap())).collect()
    }

    #[test]
    fn origins_are_allowed_when_absent_own_or_listed() {
        let listed = ["https://app.example".to_owned()];
        assert!(origin_allowed(&headers(&[]), &listed));
        let own = headers(&[(header::ORIGIN, "http://localhost:8080"), (header::HOST, "localhost:8080")]);
        assert!(origin_allowed(&own, &[]));
        assert!(origin_allowed(&headers(&[(header::ORIGIN, "https://app.example")]), &listed));
        let foreign = headers(&[(header::ORIGIN, "https://evil.example"), (header::HOST, "localhost:8080")]);
        assert!(!origin_allowed(&foreign, &listed));
        assert!(!origin_allowed(&headers(&[(header::ORIGIN, "null")]), &listed));
        assert!(origin_allowed(&foreign, &["*".to_owned()]));
    }

    #[test]
    fn a_trusted_proxy_names_the_client_and_an_untrusted_peer_is_its_own_client() {
        let trusted: Vec<IpNet> = ["10.0.0.0/8".parse().unwrap(), "::1/128".parse().unwrap()].into();
        let proxy: IpAddr = "10.1.2.3".parse().unwrap();
        let ip = |s: &str| s.parse::<IpAddr>().unwrap();
        let xff = header::HeaderName::from_static("x-forwarded-for");
        // The client's own entries come first and are not believed: the last untrusted one is.
        let chain = headers(&[(xff.clone(), "6.6.6.6, 203.0.113.7, 10.9.9.9")]);
        assert_eq!(client_address(proxy, &chain, &trusted), ip("203.0.113.7"));
        // Forwarded wins, with quotes, brackets and ports; parameters beside `for` are skipped.
        let forwarded = headers(&[
            (header::FORWARDED, r#"for=198.51.100.1;proto=http, for="[2001:db8::17]:4711""#),
            (xff.clone(), "203.0.113.7"),
        ]);
        assert_eq!(client_address(proxy, &forwarded, &trusted), ip("2001:db8::17"));
        let two_lines = headers(&[(xff.clone(), "203.0.113.7"), (xff.clone(), "198.51.100.1:80")]);
        assert_eq!(client_address(proxy, &two_lines, &trusted), ip("198.51.100.1"));
        // Only trusted proxies in the chain: the first of them. No chain: the proxy itself.
        assert_eq!(
            client_address(proxy, &headers(&[(xff.clone(), "10.0.0.5, ::1")]), &trusted),
            ip("10.0.0.5")
        );
        assert_eq!(client_address(proxy, &headers(&[(xff.clone(), "nginx")]), &trusted), proxy);
        // A peer that is not a trusted proxy cannot name another client.
        let stranger = ip("192.0.2.9");
        assert_eq!(client_address(stranger, &chain, &trusted), stranger);
        assert_eq!(client_address(proxy, &chain, &[]), proxy, "nothing trusted by default");
    }

    #[test]
    fn keys_name_their_client_without_revealing_it() {
        let mut keys = ApiKeys::default();
        keys.insert("correct horse battery staple");
        let client = keys.client_name("correct horse battery staple").unwrap();
        assert!(client.starts_with("key:") && !client.contains("horse"));
        assert_eq!(keys.client_name("correct horse battery stapler"), None);
        assert!(!format!("{keys:?}").contains("horse"));
        let auth = headers(&[(header::AUTHORIZATION, "Bearer  abc ")]);
        assert_eq!(bearer(&auth), Some("abc"));
        assert_eq!(bearer(&headers(&[(header::AUTHORIZATION, "Basic abc")])), None);
    }
}
