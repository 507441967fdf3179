//! The one rule for names users give things — worlds, exemplars, dictionaries, layers, species and
//! materials — and the shape of content ids. Names end up in URLs, store aliases, EXR channel
//! names and TOML keys, so they are restricted to `[A-Za-z0-9_-]{1,64}`.

/// The rule, worded for error messages.
pub const NAME_RULE: &str = "1–64 letters, digits, `-` or `_`";

/// Whether `name` is 1–64 ASCII letters, digits, `-` or `_`.
pub fn is_valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// Whether `s` can be a content id: 64 lowercase hex digits (a SHA-256).
pub fn is_content_id(s: &str) -> bool {
    s.len() == 64
        && s.bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_by_hand() {
        for ok in ["a", "Tien_Shan-2", &"x".repeat(64)] {
            assert!(is_valid_name(ok), "{ok}");
        }
        for bad in ["", "a b", "a.b", "é", "../x", &"x".repeat(65)] {
            assert!(!is_valid_name(bad), "{bad}");
        }
        assert!(is_content_id(&"0a".repeat(32)));
        assert!(!is_content_id(&"0A".repeat(32)));
        assert!(!is_content_id(&"0a".repeat(31)));
    }
}
