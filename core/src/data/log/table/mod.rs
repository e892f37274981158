//! A log's table, CSV or Parquet (told apart by Parquet's leading magic bytes): the names of
//! its columns, and the selected ones' values as numbers per row, a missing value NaN.

mod csv;
#[cfg(feature = "parquet")]
mod pages;
#[cfg(feature = "parquet")]
mod parquet;

use crate::error::{Error, Result};

/// The selected columns' values in row order, each `rows` long.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    pub values: Vec<Vec<f64>>,
    pub rows: usize,
}

/// A log opened: its format and its columns' names, nothing read yet.
pub enum Table<'a> {
    Csv {
        bytes: &'a [u8],
        names: Vec<String>,
    },
    #[cfg(feature = "parquet")]
    Parquet(self::parquet::File),
}

impl<'a> Table<'a> {
    pub fn open(bytes: &'a [u8]) -> Result<Self> {
        if bytes.starts_with(b"PAR1") {
            #[cfg(feature = "parquet")]
            return Ok(Table::Parquet(self::parquet::File::open(bytes)?));
            #[cfg(not(feature = "parquet"))]
            return Err(Error::invalid(
                "log",
                "a Parquet file, and this build reads CSV logs only (the core's `parquet` feature)",
            ));
        }
        Ok(Table::Csv {
            bytes,
            names: self::csv::header(bytes)?,
        })
    }

    /// "csv" or "parquet", for the import's summary.
    pub fn format(&self) -> &'static str {
        match self {
            Table::Csv { .. } => "csv",
            #[cfg(feature = "parquet")]
            Table::Parquet(_) => "parquet",
        }
    }

    pub fn names(&self) -> &[String] {
        match self {
            Table::Csv { names, .. } => names,
            #[cfg(feature = "parquet")]
            Table::Parquet(file) => file.names(),
        }
    }

    /// The columns at `at` (indices into `names`, each with the request field that selected
    /// it, for errors) of every row. With a `memory` bound, a file whose values would not fit
    /// in it is refused before any is decoded (Parquet's compression makes a small file
    /// many values).
    #[cfg_attr(not(feature = "parquet"), allow(unused_variables))]
    pub fn read(&self, at: &[(usize, &str)], memory: Option<usize>) -> Result<Columns> {
        match self {
            // A CSV cell takes at least two bytes of text ("0,"), so its values are at most
            // four times the text's size, which an upload's memory already allows for.
            Table::Csv { bytes, names } => self::csv::read(bytes, at, names),
            #[cfg(feature = "parquet")]
            Table::Parquet(file) => file.read(at, memory),
        }
        .and_then(|c| finite(c, at, self.names()))
    }
}

/// Infinities are not positions, efforts or times: refused, naming the column and row.
fn finite(c: Columns, at: &[(usize, &str)], names: &[String]) -> Result<Columns> {
    for ((col, field), v) in at.iter().zip(&c.values) {
        if let Some(row) = v.iter().position(|x| x.is_infinite()) {
            return Err(Error::invalid(
                *field,
                format!(
                    "column '{}', row {row}: {} is not a number a log may hold",
                    names[*col], v[row]
                ),
            ));
        }
    }
    Ok(c)
}

#[cfg(all(test, feature = "parquet"))]
mod tests;
