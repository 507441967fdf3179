//! Content coding of the answers whose bytes their format leaves uncompressed: vector and
//! GeoJSON tiles ([`terrasynth_tiles::TileKind::compressible`]) and a world's features GeoJSON.
//! They go out gzip-coded when the request's `Accept-Encoding` allows it ([`Coding::negotiate`]),
//! compressed once on the blocking pool ([`terrasynth_tiles::gzip`]) and cached compressed; the
//! async runtime's threads only move the bytes. (tower-http's compression layer, which the small
//! JSON answers and the web page's files go through, compresses in the body stream at every
//! request on the runtime's threads: a 54 MB features GeoJSON held a runtime thread 0.7 s.)
//!
//! Each coding of a resource is a representation of its own, with its own strong ETag (RFC 9110
//! §8.8.3: a strong validator changes with the content coding): the gzip one is the identity
//! one with `-gzip` before its closing quote. Both carry `Vary: Accept-Encoding`, so that shared
//! caches keep them apart.

use axum::http::{header, HeaderMap, HeaderValue};
use terrasynth_tiles::{gunzip, gzip, TileError};

/// How an answer's bytes are coded for transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coding {
    /// As the format writes them.
    Identity,
    /// One gzip member (`Content-Encoding: gzip`).
    Gzip,
}

impl Coding {
    /// The coding of the answer to a request with `headers`: gzip when its `Accept-Encoding`
    /// fields accept `gzip` (or `x-gzip`, or `*` without naming gzip) with a non-zero weight
    /// (RFC 9110 §12.5.3), identity otherwise (identity is always acceptable to us: a client
    /// that refuses it and gzip gets identity rather than a 406).
    pub fn negotiate(headers: &HeaderMap) -> Coding {
        let mut gzip = None;
        let mut any = None;
        let fields = headers
            .get_all(header::ACCEPT_ENCODING)
            .iter()
            .filter_map(|v| v.to_str().ok());
        for item in fields.flat_map(|v| v.split(',')) {
            let mut parts = item.split(';');
            let coding = parts.next().unwrap_or("").trim();
            let weight = parts
                .find_map(|p| {
                    let (k, v) = p.split_once('=')?;
                    k.trim().eq_ignore_ascii_case("q").then(|| v.trim())
                })
                .map_or(Some(1.0), |q| {
                    q.parse::<f32>().ok().filter(|q| q.is_finite())
                });
            // A malformed weight counts as 0: such a coding is not taken.
            let accepted = weight.unwrap_or(0.0) > 0.0;
            if coding.eq_ignore_ascii_case("gzip") || coding.eq_ignore_ascii_case("x-gzip") {
                gzip = Some(gzip.unwrap_or(false) || accepted);
            } else if coding == "*" {
                any = Some(any.unwrap_or(false) || accepted);
            }
        }
        if gzip.or(any).unwrap_or(false) {
            Coding::Gzip
        } else {
            Coding::Identity
        }
    }

    /// The strong ETag of this coding's representation, from the identity one's (`"…"`).
    pub fn etag(self, identity: &str) -> String {
        match (self, identity.strip_suffix('"')) {
            (Coding::Gzip, Some(open)) => format!("{open}-gzip\""),
            _ => identity.to_string(),
        }
    }

    /// The other coding.
    pub fn other(self) -> Coding {
        match self {
            Coding::Identity => Coding::Gzip,
            Coding::Gzip => Coding::Identity,
        }
    }

    /// This coding's bytes from the other coding's (compressed or decompressed): a client that
    /// asks for the representation a cache does not hold yet, while it holds the other, costs
    /// milliseconds instead of the tile's computation.
    pub fn from_other(self, other: &[u8]) -> Result<Vec<u8>, TileError> {
        match self {
            Coding::Gzip => gzip(other),
            Coding::Identity => gunzip(other),
        }
    }

    /// Sets the answer's `Content-Encoding` (gzip only) and `Vary: Accept-Encoding`.
    pub fn mark(self, headers: &mut HeaderMap) {
        if self == Coding::Gzip {
            headers.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
        }
        headers.append(header::VARY, HeaderValue::from_static("accept-encoding"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accept(values: &[&str]) -> Coding {
        let mut h = HeaderMap::new();
        for v in values {
            h.append(
                header::ACCEPT_ENCODING,
                HeaderValue::from_str(v).expect("header value"),
            );
        }
        Coding::negotiate(&h)
    }

    #[test]
    fn gzip_is_taken_when_accepted_with_a_positive_weight() {
        assert_eq!(accept(&[]), Coding::Identity);
        assert_eq!(accept(&["gzip"]), Coding::Gzip);
        assert_eq!(accept(&["gzip, deflate, br, zstd"]), Coding::Gzip);
        assert_eq!(accept(&["br;q=1.0, GZip;q=0.5"]), Coding::Gzip);
        assert_eq!(accept(&["x-gzip"]), Coding::Gzip);
        assert_eq!(accept(&["br", "gzip"]), Coding::Gzip);
        assert_eq!(accept(&["*"]), Coding::Gzip);
        assert_eq!(accept(&["identity"]), Coding::Identity);
        assert_eq!(accept(&["br, deflate"]), Coding::Identity);
        assert_eq!(accept(&["gzip;q=0"]), Coding::Identity);
        assert_eq!(accept(&["gzip; Q=0.000"]), Coding::Identity);
        // Naming gzip with weight 0 refuses it even when `*` would take it.
        assert_eq!(accept(&["*, gzip;q=0"]), Coding::Identity);
        assert_eq!(accept(&["*;q=0"]), Coding::Identity);
        // Malformed weights take nothing.
        assert_eq!(accept(&["gzip;q=high"]), Coding::Identity);
        assert_eq!(accept(&["gzip;q=NaN"]), Coding::Identity);
        assert_eq!(accept(&["gzip;level=1"]), Coding::Gzip);
    }

    #[test]
    fn each_coding_is_made_from_the_other() {
        let plain = b"a vector tile, a vector tile, a vector tile".to_vec();
        let coded = Coding::Gzip.from_other(&plain).expect("gzip");
        assert_eq!(coded, gzip(&plain).expect("gzip"));
        assert_eq!(Coding::Identity.from_other(&coded).expect("gunzip"), plain);
        assert_eq!(Coding::Gzip.other(), Coding::Identity);
        assert_eq!(Coding::Identity.other(), Coding::Gzip);
    }

    #[test]
    fn each_coding_has_its_own_strong_etag() {
        assert_eq!(Coding::Identity.etag("\"ab12\""), "\"ab12\"");
        assert_eq!(Coding::Gzip.etag("\"ab12\""), "\"ab12-gzip\"");
    }

    #[test]
    fn gzip_answers_say_so_and_both_vary_on_accept_encoding() {
        let mut h = HeaderMap::new();
        Coding::Gzip.mark(&mut h);
        assert_eq!(h[header::CONTENT_ENCODING], "gzip");
        assert_eq!(h[header::VARY], "accept-encoding");
        let mut h = HeaderMap::new();
        Coding::Identity.mark(&mut h);
        assert!(!h.contains_key(header::CONTENT_ENCODING));
        assert_eq!(h[header::VARY], "accept-encoding");
    }
}
