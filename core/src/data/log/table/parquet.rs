//! A log's columns read from Parquet: each leaf column named by its path ("pose.x" inside a
//! group), each selected one decoded as numbers (floats, integers, timestamps and times in
//! seconds, decimals by their scale; a null is NaN), the others never decoded.
//!
//! The decoder is the `parquet` crate's, on a file an upload may have crafted: its panics are
//! caught and become the error of an unreadable file, and with a memory bound the values a
//! file would decode to are counted from its metadata before any page is read.

use std::panic::{AssertUnwindSafe, catch_unwind};

use ::parquet::basic::{ConvertedType, LogicalType, TimeUnit, Type as Physical};
use ::parquet::column::reader::{ColumnReader, ColumnReaderImpl};
use ::parquet::data_type::DataType;
use ::parquet::file::metadata::ColumnChunkMetaData;
use ::parquet::file::reader::{FileReader, SerializedFileReader};
use ::parquet::schema::types::ColumnDescriptor;
use bytes::Bytes;

use super::{Columns, pages};
use crate::error::{Error, Result};

/// Values decoded per call: a page's worth at a time, whatever a row group's size.
const CHUNK: usize = 8192;

pub struct File {
    bytes: Bytes,
    reader: SerializedFileReader<Bytes>,
    names: Vec<String>,
}

impl File {
    pub fn open(bytes: &[u8]) -> Result<Self> {
        let bytes = Bytes::copy_from_slice(bytes);
        let reader = decoding(|| SerializedFileReader::new(bytes.clone()))?;
        let names: Vec<String> = reader
            .metadata()
            .file_metadata()
            .schema_descr()
            .columns()
            .iter()
            .map(|c| c.path().string())
            .collect();
        if names.is_empty() {
            return Err(Error::invalid("log", "a Parquet file with no columns"));
        }
        Ok(File {
            bytes,
            reader,
            names,
        })
    }

    pub fn names(&self) -> &[String] {
        &self.names
    }

    pub fn read(&self, at: &[(usize, &str)], memory: Option<usize>) -> Result<Columns> {
        let meta = self.reader.metadata();
        let schema = meta.file_metadata().schema_descr();
        let kinds = at
            .iter()
            .map(|&(col, field)| Kind::of(&schema.column(col), field, &self.names[col]))
            .collect::<Result<Vec<_>>>()?;
        let groups: Vec<usize> = meta
            .row_groups()
            .iter()
            .map(|g| usize::try_from(g.num_rows()))
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| Error::invalid("log", "a Parquet row group of negative size"))?;
        // A crafted file may claim any count: summed without wrapping, and never trusted for
        // more than a first allocation.
        let rows = (groups.iter())
            .try_fold(0usize, |a, &n| a.checked_add(n))
            .ok_or_else(|| Error::invalid("log", "a Parquet file of more rows than can be"))?;
        if let Some(memory) = memory {
            // The values kept, and each selected column's pages as they are decompressed.
            let mut pages = 0u64;
            for g in meta.row_groups() {
                for &(col, _) in at {
                    pages = pages.saturating_add(pages::claimed(self.chunk(g.column(col))?)?);
                }
            }
            let needed = 8.0 * rows as f64 * at.len() as f64 + pages as f64;
            if needed > memory as f64 {
                return Err(Error::ResourceExhausted(format!(
                    "log: its {rows} rows of {} columns would take {:.0} MB to decode, over \
                     the {:.0} MB this upload may use; import it with `graybox import` and \
                     upload the dataset",
                    at.len(),
                    needed / 1e6,
                    memory as f64 / 1e6
                )));
            }
        }
        let mut values = vec![Vec::with_capacity(rows.min(1 << 20)); at.len()];
        let mut origins = vec![None; at.len()];
        for (g, &n) in groups.iter().enumerate() {
            let group = decoding(|| self.reader.get_row_group(g))?;
            let columns = at.iter().zip(&kinds).zip(&mut values).zip(&mut origins);
            for (((&(col, _), kind), out), origin) in columns {
                let column = decoding(|| group.get_column_reader(col))?;
                let before = out.len();
                decoding(|| kind.drain(column, n, out, origin))?;
                if out.len() != before + n {
                    return Err(Error::invalid(
                        "log",
                        format!(
                            "a Parquet file whose column '{}' has {} values in row group {g} \
                             of {n} rows",
                            self.names[col],
                            out.len() - before
                        ),
                    ));
                }
            }
        }
        Ok(Columns { values, rows })
    }
}

impl File {
    #[cfg(test)]
    pub(super) fn reader(&self) -> &SerializedFileReader<Bytes> {
        &self.reader
    }

    /// A column chunk's bytes (its pages), as its metadata places them.
    pub(super) fn chunk(&self, c: &ColumnChunkMetaData) -> Result<&[u8]> {
        let start = c.dictionary_page_offset().unwrap_or(c.data_page_offset());
        let range = u64::try_from(start)
            .ok()
            .zip(u64::try_from(c.compressed_size()).ok())
            .and_then(|(s, n)| {
                Some(usize::try_from(s).ok()?..usize::try_from(s.checked_add(n)?).ok()?)
            });
        range.and_then(|r| self.bytes.get(r)).ok_or_else(|| {
            Error::invalid("log", "unreadable Parquet: a column chunk outside the file")
        })
    }
}

/// A two's-complement big-endian integer of at most 16 bytes (a decimal's unscaled value).
fn big_endian(b: &[u8]) -> i128 {
    let fill = if b.first().is_some_and(|x| x & 0x80 != 0) {
        0xff
    } else {
        0
    };
    let mut full = [fill; 16];
    full[16 - b.len().min(16)..].copy_from_slice(&b[b.len().saturating_sub(16)..]);
    i128::from_be_bytes(full)
}

/// A decoder's call: its error, or its panic on a malformed file, as the log's error.
fn decoding<T>(f: impl FnOnce() -> ::parquet::errors::Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(Error::invalid("log", format!("unreadable Parquet: {e}"))),
        Err(_) => Err(Error::invalid(
            "log",
            "unreadable Parquet: the file is malformed",
        )),
    }
}

/// How a column's stored values become numbers: the factor to seconds (a timestamp, a time or
/// a date) or by a decimal's scale.
#[derive(Debug, Clone, Copy)]
struct Kind {
    unsigned: bool,
    /// A 64-bit timestamp, read as seconds since the column's first value: nanoseconds since
    /// 1970 (a ROS header's stamp) are ~1.8e18, which an f64 holds only to 256 ns, a quarter
    /// of a 1 kHz log's jitter; their differences from the first are exact.
    stamp: bool,
    /// A decimal in big-endian bytes (a fixed-length byte array).
    decimal_bytes: bool,
    factor: f64,
    /// Nulls are possible: definition levels tell which rows have a value.
    max_def: i16,
}

impl Kind {
    fn of(c: &ColumnDescriptor, field: &str, name: &str) -> Result<Kind> {
        let refuse = |what: &str| {
            Err(Error::invalid(
                field,
                format!("column '{name}' {what}; a log's columns are numbers"),
            ))
        };
        if c.max_rep_level() > 0 {
            return refuse("is a list (repeated values in a row)");
        }
        let unit = |u: &TimeUnit| match u {
            TimeUnit::MILLIS => 1e-3,
            TimeUnit::MICROS => 1e-6,
            TimeUnit::NANOS => 1e-9,
        };
        let (mut unsigned, mut factor, mut stamp) = (false, 1.0, false);
        let is_decimal = matches!(c.logical_type_ref(), Some(LogicalType::Decimal(_)));
        match c.logical_type_ref() {
            Some(LogicalType::Timestamp(t)) => (factor, stamp) = (unit(&t.unit), true),
            Some(LogicalType::Time(t)) => factor = unit(&t.unit),
            Some(LogicalType::Date) => factor = 86_400.0,
            Some(LogicalType::Decimal(d)) => factor = 10f64.powi(-d.scale),
            Some(LogicalType::Integer(i)) => unsigned = !i.is_signed,
            _ => match c.converted_type() {
                ConvertedType::TIMESTAMP_MILLIS => (factor, stamp) = (1e-3, true),
                ConvertedType::TIMESTAMP_MICROS => (factor, stamp) = (1e-6, true),
                ConvertedType::TIME_MILLIS => factor = 1e-3,
                ConvertedType::TIME_MICROS => factor = 1e-6,
                ConvertedType::DATE => factor = 86_400.0,
                ConvertedType::UINT_32 | ConvertedType::UINT_64 => unsigned = true,
                _ => {}
            },
        }
        match c.physical_type() {
            Physical::FIXED_LEN_BYTE_ARRAY if is_decimal && c.type_length() <= 16 => Ok(Kind {
                unsigned,
                stamp: false,
                decimal_bytes: true,
                factor,
                max_def: c.max_def_level(),
            }),
            Physical::FLOAT | Physical::DOUBLE | Physical::INT32 | Physical::INT64 => Ok(Kind {
                unsigned,
                stamp,
                decimal_bytes: false,
                factor,
                max_def: c.max_def_level(),
            }),
            Physical::BOOLEAN => refuse("holds true/false"),
            Physical::INT96 => refuse(
                "holds INT96 timestamps (a legacy form: write times as INT64 timestamps or \
                 seconds as DOUBLE)",
            ),
            _ => refuse("holds text or bytes"),
        }
    }

    /// The column's `rows` values appended to `out` (a null as NaN); a timestamp's first value
    /// kept in `origin` across row groups.
    fn drain(
        &self,
        column: ColumnReader,
        rows: usize,
        out: &mut Vec<f64>,
        origin: &mut Option<i64>,
    ) -> ::parquet::errors::Result<()> {
        let f = self.factor;
        match column {
            ColumnReader::FloatColumnReader(r) => self.values(r, rows, out, |v| f64::from(*v)),
            ColumnReader::DoubleColumnReader(r) => self.values(r, rows, out, |v| *v),
            ColumnReader::Int32ColumnReader(r) if self.unsigned => {
                self.values(r, rows, out, |v| f64::from(*v as u32) * f)
            }
            ColumnReader::Int32ColumnReader(r) => self.values(r, rows, out, |v| f64::from(*v) * f),
            ColumnReader::Int64ColumnReader(r) if self.unsigned => {
                self.values(r, rows, out, |v| *v as u64 as f64 * f)
            }
            ColumnReader::Int64ColumnReader(r) if self.stamp => self.values(r, rows, out, |v| {
                let first = *origin.get_or_insert(*v);
                (i128::from(*v) - i128::from(first)) as f64 * f
            }),
            ColumnReader::Int64ColumnReader(r) => self.values(r, rows, out, |v| *v as f64 * f),
            ColumnReader::FixedLenByteArrayColumnReader(r) if self.decimal_bytes => {
                self.values(r, rows, out, |v| big_endian(v.data()) as f64 * f)
            }
            _ => unreachable!("Kind::of admits these physical types only"),
        }
    }

    fn values<T: DataType>(
        &self,
        mut r: ColumnReaderImpl<T>,
        rows: usize,
        out: &mut Vec<f64>,
        mut number: impl FnMut(&T::T) -> f64,
    ) -> ::parquet::errors::Result<()> {
        let (mut defs, mut vals) = (Vec::new(), Vec::new());
        let mut left = rows;
        while left > 0 {
            defs.clear();
            vals.clear();
            let levels = if self.max_def > 0 {
                Some(&mut defs)
            } else {
                None
            };
            let (records, _, _) = r.read_records(left.min(CHUNK), levels, None, &mut vals)?;
            if records == 0 {
                break;
            }
            if self.max_def > 0 {
                let mut given = vals.iter();
                for d in &defs {
                    let v = (*d == self.max_def).then(|| given.next()).flatten();
                    out.push(v.map_or(f64::NAN, &mut number));
                }
            } else {
                out.extend(vals.iter().map(&mut number));
            }
            left -= records.min(left);
        }
        Ok(())
    }
}
