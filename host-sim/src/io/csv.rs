//! CSV as the contract defines it: a header line, comma separators, `.` decimal point, one record
//! per line. Fields are never quoted: every column Kestrel reads or writes is a number or a name.

use std::fmt::Display;
use std::io::{self, Write};
use std::path::Path;

use super::{describe_io_error, InputError, Place};

/// Reads a points file: a header whose first two columns are `x` and `y`, then one point per
/// line. Further columns are allowed and ignored, so an output file can be fed back in.
pub fn read_points(path: &Path) -> Result<Vec<(f32, f32)>, InputError> {
    let text = read_text(path)?;
    parse_points(&text, &path.display().to_string())
}

/// Parses the text of a points file named `input` (see [`read_points`]).
pub fn parse_points(text: &str, input: &str) -> Result<Vec<(f32, f32)>, InputError> {
    let table = Table::parse(text, input, &["x", "y"])?;
    table
        .records()
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

/// One coordinate: a finite decimal number, surrounding spaces allowed.
fn parse_coordinate(field: &str) -> Result<f32, String> {
    let trimmed = field.trim();
    match trimmed.parse::<f32>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!("\"{trimmed}\" is not a finite number")),
        Err(_) => Err(format!("\"{trimmed}\" is not a number")),
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

/// One data line of a CSV file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record<'a> {
    /// Line number, from 1 (the header is line 1).
    pub line: usize,
    fields: Vec<&'a str>,
}

impl<'a> Record<'a> {
    /// The field in `column` (from 0); every record has one per header column.
    pub fn field(&self, column: usize) -> &'a str {
        self.fields.get(column).copied().unwrap_or("")
    }
}

/// A CSV text split into its header and records: the header must start with the expected
/// columns (more may follow), every record must have as many fields as the header, and blank
/// lines are skipped. A UTF-8 byte order mark is allowed.
#[derive(Debug, Clone)]
pub struct Table<'a> {
    input: String,
    header: Vec<&'a str>,
    records: Vec<Record<'a>>,
}

impl<'a> Table<'a> {
    /// Splits `text`, the contents of the file `input`, whose header must start with `columns`.
    pub fn parse(text: &'a str, input: &str, columns: &[&str]) -> Result<Self, InputError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let expected = columns.join(",");
        let mut lines = text.lines().enumerate().map(|(i, line)| (i + 1, line));
        let header: Vec<&str> = match lines.next() {
            Some((_, line)) => line.split(',').map(str::trim).collect(),
            None => {
                let problem = format!("empty file; expected a header line \"{expected}\"");
                return Err(InputError::new(input, problem));
            }
        };
        if !header.starts_with(columns) {
            let problem = format!(
                "expected a header starting with \"{expected}\", found \"{}\"",
                header.join(",")
            );
            return Err(InputError::new(input, problem).at(Place::Line(1)));
        }
        let mut records = Vec::new();
        for (line, text) in lines {
            if text.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = text.split(',').collect();
            if fields.len() != header.len() {
                let problem = format!(
                    "expected {} fields like the header, found {}",
                    header.len(),
                    fields.len()
                );
                return Err(InputError::new(input, problem).at(Place::Line(line)));
            }
            records.push(Record { line, fields });
        }
        Ok(Self {
            input: input.to_owned(),
            header,
            records,
        })
    }

    /// The records, in file order.
    pub fn records(&self) -> &[Record<'a>] {
        &self.records
    }

    /// A problem with the field in `column` (from 0) of `record`, naming line, column and
    /// header name.
    pub fn cell_error(&self, record: &Record<'_>, column: usize, problem: String) -> InputError {
        let cell = Place::Cell {
            line: record.line,
            column: column + 1,
            name: self.header.get(column).copied().unwrap_or("").to_owned(),
        };
        InputError::new(&self.input, problem).at(cell)
    }

    /// The field in `column` of `record` read by `parse` (such as [`parse_finite`]), or the
    /// problem located at its cell.
    pub fn value<T>(
        &self,
        record: &Record<'_>,
        column: usize,
        parse: impl Fn(&str) -> Result<T, String>,
    ) -> Result<T, InputError> {
        parse(record.field(column)).map_err(|problem| self.cell_error(record, column, problem))
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

    /// The underlying writer, borrowed.
    pub fn get_ref(&self) -> &W {
        &self.out
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
    fn tables_check_their_header_and_name_bad_cells() {
        let text = "t_us,gx,extra\n0,1.5,a\n\n10,nan,b\n20,x,c\n";
        let table = Table::parse(text, "g.csv", &["t_us", "gx"]).unwrap();
        let lines: Vec<usize> = table.records().iter().map(|r| r.line).collect();
        assert_eq!(lines, [2, 4, 5]);
        let records = table.records();
        assert_eq!(table.value(&records[0], 1, parse_finite), Ok(1.5));
        assert!(table.value(&records[1], 1, parse_number).unwrap().is_nan());
        assert_eq!(
            table
                .value(&records[1], 1, parse_finite)
                .unwrap_err()
                .to_string(),
            "g.csv: line 4, column 2 (gx): \"nan\" is not a finite number"
        );
        assert_eq!(
            table
                .value(&records[2], 1, parse_number)
                .unwrap_err()
                .to_string(),
            "g.csv: line 5, column 2 (gx): \"x\" is not a number"
        );
        let wrong = Table::parse("t,gx\n", "g.csv", &["t_us", "gx"]).unwrap_err();
        assert_eq!(
            wrong.to_string(),
            "g.csv: line 1: expected a header starting with \"t_us,gx\", found \"t,gx\""
        );
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
