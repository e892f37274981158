//! A log's columns read from CSV: the header names them, each selected column is parsed as
//! numbers (a missing value, `nan` or `NA`, is NaN), the others are never read, so a log may
//! carry text (a controller's mode, a comment) beside what is imported.

use super::Columns;
use crate::error::{Error, Result};

/// The header's column names.
pub fn header(bytes: &[u8]) -> Result<Vec<String>> {
    let mut reader = reader(bytes);
    let names = reader
        .headers()
        .map_err(|e| Error::invalid("log", format!("cannot read the header row: {e}")))?;
    if names.is_empty() || names.iter().all(str::is_empty) {
        return Err(Error::invalid(
            "log",
            "empty: expected a header row naming the columns",
        ));
    }
    Ok(names.iter().map(str::to_string).collect())
}

/// The columns at `at` (indices into the header) of every row; `fields` names each one's
/// request field for an error (a cell that is not a number names the field, the column and
/// the row).
pub fn read(bytes: &[u8], at: &[(usize, &str)], names: &[String]) -> Result<Columns> {
    let mut reader = reader(bytes);
    let mut values = vec![Vec::new(); at.len()];
    let mut rows = 0;
    for (row, record) in reader.records().enumerate() {
        let record = record.map_err(|e| Error::invalid("log", format!("row {row}: {e}")))?;
        if record.len() != names.len() {
            return Err(Error::invalid(
                "log",
                format!(
                    "row {row} has {} values, the header has {}",
                    record.len(),
                    names.len()
                ),
            ));
        }
        for ((col, field), out) in at.iter().zip(&mut values) {
            out.push(number(&record[*col]).ok_or_else(|| {
                Error::invalid(
                    *field,
                    format!(
                        "column '{}', row {row}: '{}' is not a number",
                        names[*col], &record[*col]
                    ),
                )
            })?);
        }
        rows += 1;
    }
    Ok(Columns { values, rows })
}

fn reader(bytes: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(bytes)
}

/// A cell as a number: empty, `nan`, `NaN` and `NA` are missing (NaN); anything else must
/// parse as f64 (infinities are not positions, efforts or times: refused).
fn number(cell: &str) -> Option<f64> {
    match cell {
        "" | "nan" | "NaN" | "NA" | "null" => Some(f64::NAN),
        _ => cell.parse::<f64>().ok().filter(|v| v.is_finite()),
    }
}
