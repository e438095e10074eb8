//! A minimal JSON object writer for the small flat summaries host-sim emits.

use std::fmt::Write;

/// Builds a one-line JSON object, keys in insertion order.
///
/// ```
/// use host_sim::io::json::JsonObject;
/// let text = JsonObject::new().integer("points", 3).number("t", 0.25).finish();
/// assert_eq!(text, "{\"points\": 3, \"t\": 0.25}\n");
/// ```
#[derive(Debug, Clone, Default)]
pub struct JsonObject {
    body: String,
}

impl JsonObject {
    /// An empty object.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds an integer member.
    pub fn integer(self, key: &str, value: u64) -> Self {
        self.member(key, &value.to_string())
    }

    /// Adds a number member; NaN and infinities, which JSON cannot express, become `null`.
    pub fn number(self, key: &str, value: f64) -> Self {
        if value.is_finite() {
            // `Display` for f64 prints the shortest text that reads back exactly, without an
            // exponent, which is valid JSON.
            self.member(key, &value.to_string())
        } else {
            self.member(key, "null")
        }
    }

    /// Adds a string member.
    pub fn string(self, key: &str, value: &str) -> Self {
        self.member(key, &quote(value))
    }

    /// Adds an object member.
    ///
    /// ```
    /// use host_sim::io::json::JsonObject;
    /// let inner = JsonObject::new().integer("lost", 2);
    /// assert_eq!(JsonObject::new().object("drops", inner).finish(), "{\"drops\": {\"lost\": 2}}\n");
    /// ```
    pub fn object(self, key: &str, value: JsonObject) -> Self {
        let inner = format!("{{{}}}", value.body);
        self.member(key, &inner)
    }

    /// The object's text, with a final newline.
    pub fn finish(self) -> String {
        format!("{{{}}}\n", self.body)
    }

    fn member(mut self, key: &str, value: &str) -> Self {
        if !self.body.is_empty() {
            self.body.push_str(", ");
        }
        self.body.push_str(&quote(key));
        self.body.push_str(": ");
        self.body.push_str(value);
        self
    }
}

/// `text` as a JSON string literal.
fn quote(text: &str) -> String {
    let mut quoted = String::with_capacity(text.len() + 2);
    quoted.push('"');
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            '\n' => quoted.push_str("\\n"),
            '\r' => quoted.push_str("\\r"),
            '\t' => quoted.push_str("\\t"),
            c if u32::from(c) < 0x20 => {
                let _ = write!(quoted, "\\u{:04x}", u32::from(c));
            }
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn members_keep_their_order_and_types() {
        let text = JsonObject::new()
            .integer("points", 12)
            .integer("repeat", 5)
            .number("median_core_seconds", 0.000125)
            .finish();
        assert_eq!(
            text,
            "{\"points\": 12, \"repeat\": 5, \"median_core_seconds\": 0.000125}\n"
        );
    }

    #[test]
    fn strings_are_escaped_and_non_finite_numbers_are_null() {
        let text = JsonObject::new()
            .string("name", "a\"b\\c\n\u{1}")
            .number("bad", f64::NAN)
            .finish();
        assert_eq!(
            text,
            "{\"name\": \"a\\\"b\\\\c\\n\\u0001\", \"bad\": null}\n"
        );
    }

    #[test]
    fn tiny_numbers_have_no_exponent() {
        let text = JsonObject::new().number("t", 1.5e-7).finish();
        assert_eq!(text, "{\"t\": 0.00000015}\n");
    }
}
