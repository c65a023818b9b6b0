//! API keys: when the service is given a key file, the scene routes answer only requests with
//! `Authorization: Bearer <key>` for one of its keys. Probes (`/healthz`, `/readyz`), the
//! metrics scrape and the API's own description (`/docs`, `/openapi.json`, `/problems/…`) stay
//! open: orchestrators and scrapers carry no keys, and the contract is no secret (a client
//! generator fetches it before it has a key).
//!
//! Keys are compared in time that does not depend on where a presented key first differs, over
//! every key, so response timing tells nothing about them; they are never logged or echoed.

use std::path::Path;

/// The keys the service accepts.
#[derive(Clone)]
pub struct ApiKeys {
    keys: Vec<Vec<u8>>,
}

impl std::fmt::Debug for ApiKeys {
    /// The count only: a key must not reach a log through a debug print of the settings.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ApiKeys({} keys)", self.keys.len())
    }
}

impl ApiKeys {
    /// One key per line; blank lines and lines starting with `#` are skipped, and each key is
    /// trimmed of surrounding whitespace. A file without any key is an error, not a service
    /// that would refuse every request.
    pub fn parse(text: &str) -> Result<ApiKeys, String> {
        let keys: Vec<Vec<u8>> = text
            .lines()
            .map(str::trim)
            .filter(|line| !line.is_empty() && !line.starts_with('#'))
            .map(|key| key.as_bytes().to_vec())
            .collect();
        if keys.is_empty() {
            return Err("it has no key (one per line; # starts a comment)".to_owned());
        }
        if let Some(n) = keys
            .iter()
            .position(|k| k.iter().any(|b| b.is_ascii_whitespace()))
        {
            return Err(format!(
                "key {} contains whitespace, which an Authorization header cannot carry",
                n + 1
            ));
        }
        Ok(ApiKeys { keys })
    }

    /// Reads the key file, naming it (never its contents) in the error.
    pub fn read(path: &Path) -> Result<ApiKeys, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("the API key file {}: {e}", path.display()))?;
        ApiKeys::parse(&text).map_err(|e| format!("the API key file {}: {e}", path.display()))
    }

    /// Whether an `Authorization` header value is `Bearer <one of the keys>`.
    pub fn allows(&self, authorization: Option<&[u8]>) -> bool {
        let Some(token) = authorization.and_then(bearer_token) else {
            return false;
        };
        // Every key is compared, so the time does not say which one (if any) came close.
        self.keys
            .iter()
            .fold(false, |found, key| found | constant_time_eq(key, token))
    }
}

/// The token of `Bearer <token>` (the scheme is case-insensitive, RFC 7235).
fn bearer_token(value: &[u8]) -> Option<&[u8]> {
    let (scheme, rest) = value.split_at_checked(6)?;
    if !scheme.eq_ignore_ascii_case(b"bearer") {
        return None;
    }
    let token = rest.trim_ascii_start();
    (token.len() < rest.len() && !token.is_empty()).then_some(token.trim_ascii_end())
}

/// Equality whose time depends on the lengths only, not on where the bytes differ.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    let longest = a.len().max(b.len());
    let mut difference = u8::from(a.len() != b.len());
    for i in 0..longest {
        let x = a.get(i).copied().unwrap_or(0);
        let y = b.get(i).copied().unwrap_or(0);
        difference |= x ^ y;
    }
    std::hint::black_box(difference) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_file_has_one_key_per_line_with_comments() {
        let keys = ApiKeys::parse("# ops team\n  k-one  \n\nk-two\n").unwrap();
        assert!(keys.allows(Some(b"Bearer k-one")));
        assert!(keys.allows(Some(b"bearer   k-two ")));
        for refused in [
            None,
            Some(&b"Bearer"[..]),
            Some(b"Bearer "),
            Some(b"Bearerk-one"),
            Some(b"Basic k-one"),
            Some(b"Bearer k-on"),
            Some(b"Bearer k-one2"),
            Some(b"Bearer # ops team"),
        ] {
            assert!(!keys.allows(refused), "{refused:?}");
        }
        assert!(ApiKeys::parse("# nothing\n\n").is_err());
        assert!(ApiKeys::parse("two words\n").is_err());
        assert_eq!(format!("{keys:?}"), "ApiKeys(2 keys)");
    }

    #[test]
    fn unequal_lengths_and_bytes_are_unequal() {
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"ab"));
        assert!(!constant_time_eq(b"", b"a"));
        // A key that is a prefix of another's padding must not match: "a\0" is not "a".
        assert!(!constant_time_eq(b"a", b"a\0"));
    }
}
