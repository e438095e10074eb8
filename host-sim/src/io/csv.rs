//! CSV as the contract defines it: a header line, comma separators, `.` decimal point, one record
//! per line. Fields are never quoted: every column Kestrel reads or writes is a number or a name.

use std::fmt::Display;
use std::io::{self, Write};
use std::path::Path;

use super::{describe_io_error, InputError, Place};

/// Reads a points file: a header whose first two columns are `x` and `y`, then one point per
/// line. Further columns are allowed and ignored, so an output file can be fed back in.
pub fn read_points(path: &Path) -> Result<Vec<(f32, f32)>, InputError> {
    let bytes = std::fs::read(path)
        .map_err(|e| InputError::file(path, format!("cannot read: {}", describe_io_error(&e))))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| InputError::file(path, "not a text file (invalid UTF-8)"))?;
    parse_points(&text, &path.display().to_string())
}

/// Parses the text of a points file named `input` (see [`read_points`]).
pub fn parse_points(text: &str, input: &str) -> Result<Vec<(f32, f32)>, InputError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text.lines().enumerate().map(|(i, line)| (i + 1, line));
    let header: Vec<&str> = match lines.next() {
        Some((_, line)) => line.split(',').map(str::trim).collect(),
        None => {
            return Err(InputError::new(
                input,
                "empty file; expected a header line \"x,y\"",
            ))
        }
    };
    if header.len() < 2 || header[0] != "x" || header[1] != "y" {
        let problem = format!(
            "expected a header starting with \"x,y\", found \"{}\"",
            header.join(",")
        );
        return Err(InputError::new(input, problem).at(Place::Line(1)));
    }
    let mut points = Vec::new();
    for (line_number, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != header.len() {
            let problem = format!(
                "expected {} fields like the header, found {}",
                header.len(),
                fields.len()
            );
            return Err(InputError::new(input, problem).at(Place::Line(line_number)));
        }
        let coordinate = |column: usize| {
            parse_coordinate(fields[column]).map_err(|problem| {
                let cell = Place::Cell {
                    line: line_number,
                    column: column + 1,
                    name: header[column].to_owned(),
                };
                InputError::new(input, problem).at(cell)
            })
        };
        points.push((coordinate(0)?, coordinate(1)?));
    }
    Ok(points)
}

/// One coordinate: a finite decimal number, surrounding spaces allowed.
fn parse_coordinate(field: &str) -> Result<f32, String> {
    let trimmed = field.trim();
    match trimmed.parse::<f32>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!("\"{trimmed}\" is not a finite number")),
        Err(_) => Err(format!("\"{trimmed}\" is not a number")),
    }
}

/// Writes CSV records with a fixed number of columns.
#[derive(Debug)]
pub struct CsvWriter<W: Write> {
    out: W,
    columns: usize,
}

impl<W: Write> CsvWriter<W> {
    /// Starts a file by writing its header line.
    pub fn new(mut out: W, header: &[&str]) -> io::Result<Self> {
        writeln!(out, "{}", header.join(","))?;
        Ok(Self {
            out,
            columns: header.len(),
        })
    }

    /// Writes one record; it must have as many fields as the header.
    pub fn record(&mut self, fields: &[&dyn Display]) -> io::Result<()> {
        debug_assert_eq!(
            fields.len(),
            self.columns,
            "record width differs from header"
        );
        for (i, field) in fields.iter().enumerate() {
            if i > 0 {
                self.out.write_all(b",")?;
            }
            write!(self.out, "{field}")?;
        }
        self.out.write_all(b"\n")
    }

    /// The underlying writer, for committing or flushing.
    pub fn into_inner(self) -> W {
        self.out
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
    fn writer_joins_fields() {
        let mut writer = CsvWriter::new(Vec::new(), &["x", "ok"]).unwrap();
        writer.record(&[&Fixed4(1.0), &1]).unwrap();
        writer.record(&[&Fixed4(-0.00001), &0]).unwrap();
        let text = String::from_utf8(writer.into_inner()).unwrap();
        assert_eq!(text, "x,ok\n1.0000,1\n0.0000,0\n");
    }
}
