//! Conditional requests (RFC 9110 §13): `If-None-Match` against the ETag an answer would carry,
//! one comparison for every route ([`none_match`]).
//!
//! Tiles and a world's features GeoJSON carry strong ETags derived from what they are computed
//! from, before any bytes exist (so that a 304 costs no synthesis). The small documents — the
//! worlds, TileJSON, styles, the OpenAPI description — and the web page's own files carry a weak
//! ETag of their bytes ([`bytes_etag`]), with `Cache-Control: no-cache`: a client or cache keeps
//! them, asks again every time (a world can be replaced through the admin API) and gets a 304
//! while they are unchanged ([`revalidated`]). Weak, because the compression layer in front of
//! those routes gzips the bytes without touching the tag, and a strong validator must change
//! with the content coding; weak tags are what `If-None-Match` compares anyway.

use axum::body::Bytes;
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

/// `Cache-Control` of the answers [`revalidated`] makes: stored, but revalidated at every use.
pub const REVALIDATE: HeaderValue = HeaderValue::from_static("no-cache");

/// Whether the request's `If-None-Match` fields name `tag` (or `*`), compared weakly (RFC 9110
/// §13.1.2: a `W/` prefix on either side is ignored). A tag with a comma inside its quotes is not
/// one we issue, so splitting the fields on commas loses nothing.
pub fn none_match(headers: &HeaderMap, tag: &str) -> bool {
    fn opaque(t: &str) -> &str {
        t.strip_prefix("W/").unwrap_or(t)
    }
    let ours = opaque(tag);
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .any(|t| t == "*" || opaque(t) == ours)
}

/// The weak ETag of a document's bytes: `W/"` and the first 16 bytes of their SHA-256 in hex.
pub fn bytes_etag(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    format!("W/\"{}\"", terrasynth_store::object::hex(&digest[..16]))
}

/// The answer to a GET of a document whose bytes are `body` and whose ETag is `tag` (its
/// [`bytes_etag`], or one computed once for a fixed document): 304 without a body when the
/// request's `If-None-Match` names it, else 200 with the body and `content_type`. Both carry the
/// ETag, `Cache-Control: no-cache` and `vary` when given.
pub fn revalidated(
    headers: &HeaderMap,
    tag: &str,
    body: Bytes,
    content_type: HeaderValue,
    vary: Option<HeaderValue>,
) -> Response {
    let mut resp = if none_match(headers, tag) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        let mut resp = body.into_response();
        resp.headers_mut()
            .insert(header::CONTENT_TYPE, content_type);
        resp
    };
    let h = resp.headers_mut();
    if let Ok(v) = HeaderValue::from_str(tag) {
        h.insert(header::ETAG, v);
    }
    h.insert(header::CACHE_CONTROL, REVALIDATE);
    if let Some(v) = vary {
        h.insert(header::VARY, v);
    }
    resp
}

/// [`revalidated`] for a value serialised as JSON (`application/json`), tagged by its bytes.
pub fn revalidated_json<T: serde::Serialize>(
    headers: &HeaderMap,
    value: &T,
    vary: Option<HeaderValue>,
) -> Response {
    match serde_json::to_vec(value) {
        Ok(body) => revalidated(
            headers,
            &bytes_etag(&body),
            body.into(),
            HeaderValue::from_static("application/json"),
            vary,
        ),
        Err(e) => super::ServerError::Internal(format!("JSON answer: {e}")).into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn asking(fields: &[&str]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for f in fields {
            h.append(header::IF_NONE_MATCH, HeaderValue::from_str(f).unwrap());
        }
        h
    }

    #[test]
    fn if_none_match_compares_weakly_across_lists_and_fields() {
        let strong = "\"ab12\"";
        let weak = "W/\"ab12\"";
        for tag in [strong, weak] {
            assert!(none_match(&asking(&["\"ab12\""]), tag));
            assert!(none_match(&asking(&["W/\"ab12\""]), tag));
            assert!(none_match(&asking(&["\"x\", W/\"ab12\""]), tag));
            assert!(none_match(&asking(&["\"x\"", "\"ab12\""]), tag));
            assert!(none_match(&asking(&["*"]), tag));
            assert!(!none_match(&asking(&[]), tag));
            assert!(!none_match(&asking(&["\"ab12-gzip\""]), tag));
            assert!(!none_match(&asking(&["\"ab1\", \"x\""]), tag));
        }
    }

    #[test]
    fn a_documents_tag_follows_its_bytes() {
        let a = bytes_etag(b"{\"a\":1}");
        assert!(a.starts_with("W/\"") && a.ends_with('"') && a.len() == 3 + 32 + 1);
        assert_eq!(a, bytes_etag(b"{\"a\":1}"));
        assert_ne!(a, bytes_etag(b"{\"a\":2}"));
    }

    #[test]
    fn revalidation_answers_304_with_the_same_headers_and_no_body() {
        let tag = bytes_etag(b"doc");
        let vary = Some(HeaderValue::from_static("Host"));
        let json = HeaderValue::from_static("application/json");
        let full = revalidated(&asking(&[]), &tag, "doc".into(), json.clone(), vary.clone());
        assert_eq!(full.status(), StatusCode::OK);
        assert_eq!(full.headers()[header::CONTENT_TYPE], "application/json");
        let again = revalidated(&asking(&[&tag]), &tag, "doc".into(), json, vary);
        assert_eq!(again.status(), StatusCode::NOT_MODIFIED);
        for h in [header::ETAG, header::CACHE_CONTROL, header::VARY] {
            assert_eq!(full.headers()[&h], again.headers()[&h], "{h}");
        }
        assert_eq!(again.headers()[header::CACHE_CONTROL], "no-cache");
        assert!(again.headers().get(header::CONTENT_TYPE).is_none());
    }
}
