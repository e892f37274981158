//! Parquet logs written by pyarrow (tests/fixtures/logs/make_parquet.py writes them).

use super::*;
use crate::data::log::{ImportOptions, LogColumns, column_list, import_log};
use crate::rng::Rng;

fn fixture(path: &str) -> Vec<u8> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    std::fs::read(root.join(path)).unwrap()
}

fn columns(time: &str, q: &str, u: &str) -> LogColumns {
    LogColumns {
        time: time.into(),
        q: column_list(q),
        qdot: vec![],
        qddot: vec![],
        u: column_list(u),
    }
}

/// The committed pendulum log as pyarrow wrote it (nulls for its empty cells, row groups of
/// 200 rows, snappy) imports exactly as its CSV does: the same dataset, bit for bit, and the
/// same summary but for the format.
#[test]
fn a_parquet_log_imports_as_its_csv_does() {
    let cols = columns("time", "theta", "tau");
    let opts = ImportOptions::default();
    let csv = import_log(&fixture("examples/logs/pendulum.csv"), &cols, &opts).unwrap();
    let parquet = import_log(&fixture("examples/logs/pendulum.parquet"), &cols, &opts).unwrap();
    assert_eq!(
        (csv.1.format.as_str(), parquet.1.format.as_str()),
        ("csv", "parquet")
    );
    assert!(
        parquet.1.dropped_rows > 0 && parquet.1.pauses > 0,
        "{:?}",
        parquet.1
    );
    let mut summary = parquet.1.clone();
    summary.format = "csv".into();
    assert_eq!(summary, csv.1);
    assert_eq!(parquet.0, csv.0);
}

/// One log's times and values in the types writers use read as the same numbers: timestamps
/// in ms, µs and ns as seconds since their first, float32, a decimal by its scale, int32 and uint64, a null as NaN.
#[test]
fn parquet_types_read_as_seconds_and_numbers() {
    let bytes = fixture("tests/fixtures/logs/types.parquet");
    let table = Table::open(&bytes).unwrap();
    let names = table.names().to_vec();
    let pick = |name: &str| {
        let col = names.iter().position(|n| n == name).unwrap();
        table.read(&[(col, "q")], None).unwrap().values.remove(0)
    };
    let seconds = pick("t_s");
    assert_eq!(seconds.len(), 12);
    // A timestamp's count times 1e-3, 1e-6 or 1e-9 against Python's count / 1000: an ulp
    // apart. The nanoseconds since 1970 count from their first value: as f64 seconds they
    // would be 2.4e-7 s apart.
    for other in ["t_ms", "t_us", "t_ns"] {
        let t = pick(other);
        assert!(
            t.iter().zip(&seconds).all(|(a, b)| (a - b).abs() < 1e-15),
            "{other}: {t:?}"
        );
    }
    let q: Vec<f64> = (0..12).map(|k| 0.125 * k as f64 - 0.5).collect();
    assert_eq!(pick("q_f32"), q, "float32 holds multiples of 1/8 exactly");
    assert!(
        pick("q_dec")
            .iter()
            .zip(&q)
            .all(|(a, b)| (a - b).abs() < 1e-15)
    );
    let u: Vec<f64> = (0..12)
        .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    assert_eq!(pick("u_i32"), u);
    assert_eq!(pick("u_u64"), u.iter().map(|v| v + 1.0).collect::<Vec<_>>());
    let gap = pick("q_gap");
    assert!(gap[3].is_nan() && gap.iter().filter(|v| v.is_nan()).count() == 1);
}

/// Columns a log cannot hold are refused naming the request's field and the column; nothing
/// is imported.
#[test]
fn parquet_columns_that_are_not_numbers_are_refused_by_name() {
    let bytes = fixture("tests/fixtures/logs/types.parquet");
    let opts = ImportOptions::default();
    for (q, says) in [
        ("mode", "holds text"),
        ("flag", "holds true/false"),
        ("pair.list.element", "is a list"),
        ("empty", "has no value in any of the 12 rows"),
        (
            "nothing",
            "no column 'nothing' in the log; its columns: t_ms, t_us, t_s, t_ns",
        ),
    ] {
        let e = import_log(&bytes, &columns("t_s", q, "u_f64"), &opts).unwrap_err();
        let Error::Invalid { field, message } = &e else {
            panic!("{q}: {e:?}")
        };
        assert_eq!(field, "q", "{q}: {e:?}");
        assert!(
            message.contains(says) && message.contains(q),
            "{q}: {message}"
        );
    }
}

/// With a memory bound, a file is refused before decoding when its values and its pages'
/// claimed sizes would not fit, as a resource limit.
#[test]
fn a_parquet_log_over_the_memory_bound_is_refused_before_decoding() {
    let bytes = fixture("examples/logs/pendulum.parquet");
    let table = Table::open(&bytes).unwrap();
    let at = [(0, "time"), (2, "q"), (3, "u")];
    let rows = table.read(&at, None).unwrap().rows;
    let e = table.read(&at, Some(8 * 3 * rows)).unwrap_err();
    assert!(
        matches!(&e, Error::ResourceExhausted(m) if m.contains("to decode")),
        "{e:?}"
    );
    assert!(table.read(&at, Some(1 << 20)).is_ok());
}

/// The page walk reads what pyarrow wrote: per column chunk, its pages' claimed sizes add up
/// to the chunk's uncompressed size less its page headers (which the metadata counts too).
#[test]
fn page_claims_add_up_to_the_metadata_of_a_written_file() {
    let bytes = fixture("examples/logs/pendulum.parquet");
    let Table::Parquet(file) = Table::open(&bytes).unwrap() else {
        panic!("not Parquet")
    };
    let meta = ::parquet::file::reader::FileReader::metadata(file.reader());
    for g in meta.row_groups() {
        for c in g.columns() {
            let claimed = pages::claimed(file.chunk(c).unwrap()).unwrap();
            let total = c.uncompressed_size() as u64;
            // A page header is tens of bytes; a chunk here has at most three pages.
            assert!(
                claimed < total && claimed + 200 > total,
                "{claimed} of {total}"
            );
        }
    }
}

/// A header that nests deeper than any page header does is malformed, not a deep recursion;
/// one that claims bytes past the chunk ends the walk there.
#[test]
fn page_headers_nested_without_end_are_refused() {
    // Field 5 a struct, holding field 1 a struct, and so on, 10⁴ deep.
    let mut deep = vec![0x15, 0x00, 0x15, 0xc8, 0x01, 0x15, 0x14, 0x2c];
    deep.extend(std::iter::repeat_n(0x1c, 10_000));
    assert!(pages::claimed(&deep).is_err());
    // type 0, uncompressed 100, compressed 10, a data page header {1: 2}, then 10 bytes.
    let mut page = vec![
        0x15, 0x00, 0x15, 0xc8, 0x01, 0x15, 0x14, 0x2c, 0x15, 0x04, 0x00, 0x00,
    ];
    page.extend([0u8; 10]);
    assert_eq!(pages::claimed(&page).unwrap(), 100);
    assert_eq!(pages::claimed(&[page.clone(), page].concat()).unwrap(), 200);
}

/// Truncated or corrupted files, as an upload may send them, are errors or (a flipped value
/// byte) another log, never a panic out of the import nor an allocation past the bound.
#[test]
fn corrupted_parquet_logs_are_errors() {
    let bytes = fixture("examples/logs/pendulum.parquet");
    let cols = columns("time", "theta", "tau");
    let opts = ImportOptions {
        memory: Some(16 << 20),
        ..ImportOptions::default()
    };
    let e = import_log(&bytes[..bytes.len() / 2], &cols, &opts).unwrap_err();
    assert!(
        matches!(&e, Error::Invalid { field, .. } if field == "log"),
        "{e:?}"
    );
    let mut rng = Rng::derive(5, 79);
    let mut refused = 0;
    for _ in 0..300 {
        let mut bad = bytes.clone();
        for _ in 0..4 {
            let at = (rng.uniform() * bad.len() as f64) as usize;
            bad[at] = (rng.uniform() * 256.0) as u8;
        }
        refused += usize::from(import_log(&bad, &cols, &opts).is_err());
    }
    assert!(refused > 0);
}
