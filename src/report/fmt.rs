//! Number and text formatting shared by the tables, the page and the sheets.
//!
//! Tables show rounded numbers for reading, while CSV files and `data-value` attributes carry the
//! exact `f64` (shortest round-trip form), so a reader can check the rounding against the manifest.

/// `x` rounded to four significant digits: fixed notation in the range tables usually see,
/// scientific outside it so tiny KL values do not turn into a row of zeros.
pub fn sig(x: f64) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    if x == 0.0 {
        return "0".into();
    }
    let e = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&e) {
        return format!("{x:.3e}");
    }
    let decimals = (3 - e).max(0) as usize;
    let s = format!("{x:.decimals$}");
    // Rounding can carry into a new digit (9.9996 → 10.000); drop the surplus decimal.
    let digits = s.chars().filter(|c| c.is_ascii_digit()).collect::<String>();
    if decimals > 0 && digits.trim_start_matches('0').len() > 4 {
        let d = decimals - 1;
        return format!("{x:.d$}");
    }
    s
}

/// The exact value in its shortest round-trip form (`0.1`, `1e-20`, `50.0`), which both Rust's
/// `f64::from_str` and JavaScript's `Number()` read back to the same double.
pub fn full(x: f64) -> String {
    format!("{x:?}")
}

/// Escapes text for HTML element content and double-quoted attribute values.
pub fn html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// Quotes a CSV field when it needs it (RFC 4180).
pub fn csv(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// A string usable as a file-name component: keeps `[A-Za-z0-9._-]`, replaces the rest.
pub fn file_stem(s: &str) -> String {
    let cleaned: String = s.chars().map(|c| if c.is_ascii_alphanumeric() || "._-".contains(c) { c } else { '_' }).collect();
    let cleaned = cleaned.trim_start_matches('.').to_string();
    if cleaned.is_empty() { "_".into() } else { cleaned }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_significant_digits() {
        assert_eq!(sig(0.0123456), "0.01235");
        assert_eq!(sig(1.23456), "1.235");
        assert_eq!(sig(123.456), "123.5");
        assert_eq!(sig(12345.6), "12346");
        assert_eq!(sig(9.99996), "10.00");
        assert_eq!(sig(-0.5), "-0.5000");
        assert_eq!(sig(0.0), "0");
        assert_eq!(sig(1.5e-7), "1.500e-7");
    }

    #[test]
    fn full_precision_round_trips() {
        for x in [0.1, 1e-20, 50.0, 0.012345678901234567, f64::MIN_POSITIVE] {
            assert_eq!(full(x).parse::<f64>().unwrap(), x);
        }
    }

    #[test]
    fn escaping() {
        assert_eq!(html("a<b & \"c\"'"), "a&lt;b &amp; &quot;c&quot;&#39;");
        assert_eq!(csv("plain"), "plain");
        assert_eq!(csv("a,b"), "\"a,b\"");
        assert_eq!(csv("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(file_stem("../a b/c"), "_a_b_c");
    }
}
