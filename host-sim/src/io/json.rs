//! `--stats` summaries: serde_json values written on one line as `{"key": value, ...}`, keys in
//! insertion order, NaN and infinities as `null` (JSON cannot express them).

use std::io;

use serde::Serialize;
use serde_json::ser::{CompactFormatter, Formatter, Serializer};

/// `value` as one line of JSON with a space after each `:` and `,`, and a final newline.
///
/// ```
/// use host_sim::io::json::one_line;
/// let value = serde_json::json!({"points": 3, "t": 0.25, "drops": {"lost": 2}, "bad": f64::NAN});
/// assert_eq!(one_line(&value), "{\"points\": 3, \"t\": 0.25, \"drops\": {\"lost\": 2}, \"bad\": null}\n");
/// ```
pub fn one_line(value: &impl Serialize) -> String {
    let mut out = Vec::new();
    let mut serializer = Serializer::with_formatter(&mut out, Spaced);
    value
        .serialize(&mut serializer)
        .expect("a JSON value serializes into memory");
    out.push(b'\n');
    String::from_utf8(out).expect("serde_json writes UTF-8")
}

/// serde_json's compact layout with the spaces the summaries have always had.
struct Spaced;

impl Formatter for Spaced {
    fn begin_object_key<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        if first {
            Ok(())
        } else {
            w.write_all(b", ")
        }
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        w.write_all(b": ")
    }

    fn begin_array_value<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        CompactFormatter.begin_array_value(w, first)?;
        if first {
            Ok(())
        } else {
            w.write_all(b" ")
        }
    }
}
