//! CSV as the contract defines it (a header line, comma separators, `.` decimal point, one
//! record per line), read and written with the `csv` crate and serde. What is kept here is the
//! contract's error wording: a bad file is named to its line, column and header name.

use std::fmt::Display;
use std::io::{self, Write};
use std::path::Path;

use serde::{Serialize, Serializer};

use super::{describe_io_error, InputError, Place};

/// Reads a points file: a header whose first two columns are `x` and `y`, then one point per
/// line. Further columns are allowed and ignored, so an output file can be fed back in.
pub fn read_points(path: &Path) -> Result<Vec<(f32, f32)>, InputError> {
    let text = read_text(path)?;
    parse_points(&text, &path.display().to_string())
}

/// Parses the text of a points file named `input` (see [`read_points`]).
pub fn parse_points(text: &str, input: &str) -> Result<Vec<(f32, f32)>, InputError> {
    let table = Table::read(text, input, &["x", "y"])?;
    table
        .records
        .iter()
        .map(|record| {
            let x = table.value(record, 0, parse_coordinate)?;
            let y = table.value(record, 1, parse_coordinate)?;
            Ok((x, y))
        })
        .collect()
}

/// The whole of a text file.
pub fn read_text(path: &Path) -> Result<String, InputError> {
    let bytes = std::fs::read(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {}", describe_io_error(&e))))?;
    String::from_utf8(bytes).map_err(|_| InputError::file(path, "not a text file (invalid UTF-8)"))
}

/// A CSV file read by the csv crate: its header, which must start with the expected columns
/// (more may follow), and its records, each as long as the header. Fields are trimmed, blank
/// lines skipped, a UTF-8 byte order mark allowed.
///
/// Fields are converted one by one ([`Table::value`]) rather than by serde's derive: the csv
/// crate does not say which column a field's own deserialization error came from, and the
/// contract's messages name the line, the column and its header.
#[derive(Debug, Clone)]
pub struct Table {
    input: String,
    header: csv::StringRecord,
    /// The records, in file order.
    pub records: Vec<csv::StringRecord>,
}

impl Table {
    /// Reads `text`, the contents of the file `input`, whose header must start with `columns`.
    pub fn read(text: &str, input: &str, columns: &[&str]) -> Result<Self, InputError> {
        let expected = columns.join(",");
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let header = reader.headers().map_err(|e| csv_error(input, &e))?.clone();
        if header.is_empty() {
            let problem = format!("empty file; expected a header line \"{expected}\"");
            return Err(InputError::new(input, problem));
        }
        if header.len() < columns.len() || !header.iter().zip(columns).all(|(h, c)| h == *c) {
            let found: Vec<&str> = header.iter().collect();
            let problem = format!(
                "expected a header starting with \"{expected}\", found \"{}\"",
                found.join(",")
            );
            return Err(InputError::new(input, problem).at(Place::Line(1)));
        }
        let records = reader
            .records()
            .collect::<Result<_, _>>()
            .map_err(|e| csv_error(input, &e))?;
        Ok(Self {
            input: input.to_owned(),
            header,
            records,
        })
    }

    /// The line of `record`, from 1 (the header is line 1).
    pub fn line(record: &csv::StringRecord) -> usize {
        record.position().map_or(0, |p| p.line() as usize)
    }

    /// A problem with the field in `column` (from 0) of `record`, naming line, column and
    /// header name.
    pub fn cell_error(
        &self,
        record: &csv::StringRecord,
        column: usize,
        problem: String,
    ) -> InputError {
        let cell = Place::Cell {
            line: Self::line(record),
            column: column + 1,
            name: self.header.get(column).unwrap_or("").to_owned(),
        };
        InputError::new(&self.input, problem).at(cell)
    }

    /// The field in `column` of `record` read by `parse` (such as [`parse_finite`]), or the
    /// problem located at its cell.
    pub fn value<T>(
        &self,
        record: &csv::StringRecord,
        column: usize,
        parse: impl Fn(&str) -> Result<T, String>,
    ) -> Result<T, InputError> {
        let field = record.get(column).unwrap_or("");
        parse(field).map_err(|problem| self.cell_error(record, column, problem))
    }
}

/// A csv error other than a field's: a record of the wrong length, a stray byte.
fn csv_error(input: &str, error: &csv::Error) -> InputError {
    match error.kind() {
        csv::ErrorKind::UnequalLengths {
            pos,
            expected_len,
            len,
        } => {
            let problem = format!("expected {expected_len} fields like the header, found {len}");
            let line = pos.as_ref().map_or(0, |p| p.line() as usize);
            InputError::new(input, problem).at(Place::Line(line))
        }
        csv::ErrorKind::Utf8 { pos, .. } => {
            let line = pos.as_ref().map_or(0, |p| p.line() as usize);
            InputError::new(input, "not a text file (invalid UTF-8)").at(Place::Line(line))
        }
        _ => InputError::new(input, error.to_string()),
    }
}

/// One coordinate: a finite decimal number (as an `f32` too: `1e39` is not).
fn parse_coordinate(field: &str) -> Result<f32, String> {
    match parse_number(field)? as f32 {
        value if value.is_finite() => Ok(value),
        _ => Err(format!("\"{}\" is not a finite number", field.trim())),
    }
}

/// A decimal number, surrounding spaces allowed; `NaN` and `inf` are numbers too.
pub fn parse_number(field: &str) -> Result<f64, String> {
    let trimmed = field.trim();
    trimmed
        .parse::<f64>()
        .map_err(|_| format!("\"{trimmed}\" is not a number"))
}

/// A decimal number that must be finite, surrounding spaces allowed.
pub fn parse_finite(field: &str) -> Result<f64, String> {
    match parse_number(field)? {
        value if value.is_finite() => Ok(value),
        _ => Err(format!("\"{}\" is not a finite number", field.trim())),
    }
}

/// Writes CSV records, each a tuple or struct serde serializes, after a header written at once
/// (a file with no records still has its header).
#[derive(Debug)]
pub struct CsvWriter<W: Write> {
    out: csv::Writer<W>,
}

impl<W: Write> CsvWriter<W> {
    /// Starts a file by writing its header line.
    pub fn new(out: W, header: &[&str]) -> io::Result<Self> {
        let mut out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(out);
        out.write_record(header)?;
        Ok(Self { out })
    }

    /// Writes one record; it must have as many fields as the header.
    pub fn record(&mut self, fields: impl Serialize) -> io::Result<()> {
        Ok(self.out.serialize(fields)?)
    }

    /// The underlying writer, borrowed.
    pub fn get_ref(&self) -> &W {
        self.out.get_ref()
    }

    /// The underlying writer once every record is flushed to it, for committing.
    pub fn finish(self) -> io::Result<W> {
        self.out.into_inner().map_err(|e| e.into_error())
    }
}

/// A coordinate or residual with the 4 decimals output files use (0.0001 px is far below what
/// LK resolves, and a fixed width keeps files diffable).
#[derive(Debug, Clone, Copy)]
pub struct Fixed4(pub f64);

impl Display for Fixed4 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // `-0.0000` would read as a sign flip in diffs of nearly-zero values.
        let value = if self.0.abs() < 0.00005 { 0.0 } else { self.0 };
        write!(f, "{value:.4}")
    }
}

impl Serialize for Fixed4 {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_are_read_in_order() {
        let text = "x,y\n1.5,2\n -3 , 4e1 \r\n\n7,8\n";
        let points = parse_points(text, "p.csv").unwrap();
        assert_eq!(points, [(1.5, 2.0), (-3.0, 40.0), (7.0, 8.0)]);
    }

    #[test]
    fn extra_columns_are_ignored_and_a_bom_is_skipped() {
        let text = "\u{feff}x,y,nx\n1,2,3\n";
        assert_eq!(parse_points(text, "p.csv").unwrap(), [(1.0, 2.0)]);
    }

    #[test]
    fn a_header_alone_is_no_points() {
        assert!(parse_points("x,y\n", "p.csv").unwrap().is_empty());
    }

    #[test]
    fn a_bad_number_names_line_and_column() {
        let error = parse_points("x,y\n1,2\n3,abc\n", "p.csv").unwrap_err();
        assert_eq!(
            error.to_string(),
            "p.csv: line 3, column 2 (y): \"abc\" is not a number"
        );
        let error = parse_points("x,y\nnan,2\n", "p.csv").unwrap_err();
        assert_eq!(
            error.to_string(),
            "p.csv: line 2, column 1 (x): \"nan\" is not a finite number"
        );
    }

    #[test]
    fn header_and_field_count_are_checked() {
        let missing_header = parse_points("1,2\n", "p.csv").unwrap_err();
        assert_eq!(missing_header.place, Some(Place::Line(1)));
        let short = parse_points("x,y\n1\n", "p.csv").unwrap_err();
        assert_eq!(short.place, Some(Place::Line(2)));
        assert!(parse_points("", "p.csv").is_err());
    }

    #[test]
    fn writer_writes_the_header_and_serialized_records() {
        let mut writer = CsvWriter::new(Vec::new(), &["x", "ok"]).unwrap();
        writer.record((Fixed4(1.0), 1)).unwrap();
        writer.record((Fixed4(-0.00001), 0)).unwrap();
        let text = String::from_utf8(writer.finish().unwrap()).unwrap();
        assert_eq!(text, "x,ok\n1.0000,1\n0.0000,0\n");
    }
}
