//! Digests and canonical JSON: the vocabulary of provenance.
//!
//! Every digest texsyn records is SHA-256 written as `{"sha256": "<hex>"}`. Digests of structured
//! data are taken over canonical JSON (RFC 8785, JCS) so that anyone can recompute them from the
//! manifest with any JCS implementation. Pixel digests are taken over a small canonical header plus
//! the raw samples, so they depend on pixels only, never on how a file happens to be compressed.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest as _, Sha256};
use std::fmt::Write as _;

/// A SHA-256 digest as recorded in manifests and golden files.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Digest {
    pub sha256: String,
}

impl Digest {
    pub fn of_bytes(bytes: &[u8]) -> Digest {
        Digest { sha256: hex(&Sha256::digest(bytes)) }
    }

    /// Digest of the canonical (RFC 8785) form of a JSON value.
    pub fn of_json(value: &Value) -> Digest {
        Digest::of_bytes(canonical_json(value).as_bytes())
    }

    /// A short prefix for messages.
    pub fn short(&self) -> &str {
        &self.sha256[..self.sha256.len().min(12)]
    }
}

impl std::fmt::Display for Digest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "sha256:{}", self.sha256)
    }
}

/// Streaming SHA-256 for large inputs (pixel buffers, files).
pub struct Hasher(Sha256);

impl Hasher {
    pub fn new() -> Hasher {
        Hasher(Sha256::new())
    }
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }
    pub fn finish(self) -> Digest {
        Digest { sha256: hex(&self.0.finalize()) }
    }
}

impl Default for Hasher {
    fn default() -> Self {
        Hasher::new()
    }
}

fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// Serialises `value` as RFC 8785 canonical JSON: object members sorted by their UTF-16 code
/// units, no insignificant whitespace, minimal string escaping, ECMAScript number formatting.
pub fn canonical_json(value: &Value) -> String {
    let mut out = String::new();
    write_canonical(value, &mut out);
    out
}

fn write_canonical(value: &Value, out: &mut String) {
    match value {
        Value::Null => out.push_str("null"),
        Value::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                // Integers outside ±2^53 would lose precision as IEEE doubles; JCS formats every
                // number as a double, so do the same for them.
                if i.unsigned_abs() <= 1 << 53 {
                    let _ = write!(out, "{i}");
                } else {
                    out.push_str(&ecmascript_number(i as f64));
                }
            } else if let Some(u) = n.as_u64() {
                if u <= 1 << 53 {
                    let _ = write!(out, "{u}");
                } else {
                    out.push_str(&ecmascript_number(u as f64));
                }
            } else {
                out.push_str(&ecmascript_number(n.as_f64().unwrap_or(f64::NAN)));
            }
        }
        Value::String(s) => write_string(s, out),
        Value::Array(items) => {
            out.push('[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_canonical(item, out);
            }
            out.push(']');
        }
        Value::Object(map) => {
            let mut keys: Vec<&String> = map.keys().collect();
            keys.sort_by(|a, b| a.encode_utf16().cmp(b.encode_utf16()));
            out.push('{');
            for (i, k) in keys.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_string(k, out);
                out.push(':');
                write_canonical(&map[*k], out);
            }
            out.push('}');
        }
    }
}

fn write_string(s: &str, out: &mut String) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\u{08}' => out.push_str("\\b"),
            '\u{09}' => out.push_str("\\t"),
            '\u{0A}' => out.push_str("\\n"),
            '\u{0C}' => out.push_str("\\f"),
            '\u{0D}' => out.push_str("\\r"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// ECMAScript `Number.prototype.toString` for a finite double (what JCS prescribes). Non-finite
/// values cannot occur in JSON; they are written as `null`.
pub fn ecmascript_number(v: f64) -> String {
    if !v.is_finite() {
        return "null".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let sign = if v < 0.0 { "-" } else { "" };
    // Rust's `{:e}` gives the shortest round-trip digits, like ECMAScript's algorithm.
    let sci = format!("{:e}", v.abs());
    let (mantissa, exp) = sci.split_once('e').expect("exponent");
    let exp: i32 = exp.parse().expect("exponent");
    let digits: String = mantissa.chars().filter(|c| *c != '.').collect();
    let k = digits.len() as i32;
    let n = exp + 1; // position of the decimal point relative to the digits
    let body = if k <= n && n <= 21 {
        format!("{digits}{}", "0".repeat((n - k) as usize))
    } else if 0 < n && n <= 21 {
        format!("{}.{}", &digits[..n as usize], &digits[n as usize..])
    } else if -6 < n && n <= 0 {
        format!("0.{}{digits}", "0".repeat((-n) as usize))
    } else {
        let e = n - 1;
        let esign = if e < 0 { "-" } else { "+" };
        if k == 1 { format!("{digits}e{esign}{}", e.abs()) } else { format!("{}.{}e{esign}{}", &digits[..1], &digits[1..], e.abs()) }
    };
    format!("{sign}{body}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn sha256_known_vector() {
        assert_eq!(Digest::of_bytes(b"abc").sha256, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }

    #[test]
    #[allow(clippy::excessive_precision)] // the RFC 8785 examples, digit for digit
    fn ecmascript_numbers_match_rfc8785_examples() {
        let cases: &[(f64, &str)] = &[
            (0.0, "0"),
            (-0.0, "0"),
            (1.0, "1"),
            (0.1, "0.1"),
            (-1.5, "-1.5"),
            (1e21, "1e+21"),
            (1e20, "100000000000000000000"),
            (1e-7, "1e-7"),
            (0.000001, "0.000001"),
            (123456789.125, "123456789.125"),
            (4.50, "4.5"),
            (2e-3, "0.002"),
            (5e-324, "5e-324"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (333333333.33333329, "333333333.3333333"),
            (9007199254740994.0, "9007199254740994"),
            (1.2345e-10, "1.2345e-10"),
        ];
        for (v, want) in cases {
            assert_eq!(ecmascript_number(*v), *want, "{v}");
        }
    }

    #[test]
    fn canonical_json_sorts_keys_and_escapes_minimally() {
        let v = json!({"b": [1, 2.5, "x\u{1}y"], "a": {"z": null, "é": true, "\r": false}, "A": "\"\\/"});
        assert_eq!(canonical_json(&v), r#"{"A":"\"\\/","a":{"\r":false,"z":null,"é":true},"b":[1,2.5,"x\u0001y"]}"#);
    }

    #[test]
    fn key_order_uses_utf16_code_units() {
        // U+1F600 (surrogates D83D DE00) sorts before U+FB01 in UTF-16 but after it in UTF-8.
        let v = json!({"\u{FB01}": 1, "\u{1F600}": 2});
        assert_eq!(canonical_json(&v), "{\"\u{1F600}\":2,\"\u{FB01}\":1}");
    }

    #[test]
    fn digest_of_json_ignores_member_order() {
        let a: Value = serde_json::from_str(r#"{"x":1,"y":[true,0.5]}"#).unwrap();
        let b: Value = serde_json::from_str(r#"{ "y" : [true, 5e-1], "x" : 1.0 }"#).unwrap();
        assert_eq!(Digest::of_json(&a), Digest::of_json(&b));
    }
}
