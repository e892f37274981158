//! The files of `--tls-cert` and `--tls-key`: read with a bound, and the certificate's
//! validity period read from real certificates (made by Python's `cryptography`; notBefore
//! and notAfter before 2050 are UTCTime, from 2050 on GeneralizedTime).

use std::path::{Path, PathBuf};

use chrono::SecondsFormat;
use graybox::api::tls::{FILE_LIMIT, TlsFiles, certificates, validity};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/tls")
        .join(name)
}

#[test]
fn validity_periods_of_real_certificates() {
    for (file, not_before, not_after) in [
        (
            "expired.pem",
            "2020-01-02T03:04:05Z",
            "2021-06-07T08:09:10Z",
        ),
        ("future.pem", "2051-01-02T03:04:05Z", "2052-06-07T08:09:10Z"),
    ] {
        let certs = certificates(&fixture(file)).unwrap();
        let (b, a) = validity(&certs[0]).unwrap();
        let show = |t: chrono::DateTime<chrono::Utc>| t.to_rfc3339_opts(SecondsFormat::Secs, true);
        assert_eq!(
            (show(b).as_str(), show(a).as_str()),
            (not_before, not_after),
            "{file}"
        );
        // Cut anywhere, or not DER at all: no period, and no panic.
        for n in 0..certs[0].len() {
            assert_eq!(validity(&certs[0][..n]), None, "{file} cut at {n}");
        }
    }
    assert_eq!(validity(b"not a certificate"), None);
}

#[test]
fn files_over_the_limit_are_refused_naming_the_flag() {
    let err = certificates(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("--tls-cert") && err.contains("1 MiB") && err.contains("/dev/zero"),
        "{err}"
    );
    // A file exactly at the limit is read; one byte more is not.
    let dir = tempfile::tempdir().unwrap();
    let pem = std::fs::read(fixture("expired.pem")).unwrap();
    for (extra, ok) in [(0, true), (1, false)] {
        let mut padded = pem.clone();
        padded.resize(FILE_LIMIT as usize + extra, b'\n');
        let path = dir.path().join(format!("padded{extra}.pem"));
        std::fs::write(&path, padded).unwrap();
        assert_eq!(certificates(&path).is_ok(), ok, "{extra}");
    }
    let files = TlsFiles {
        cert: fixture("expired.pem"),
        key: "/dev/zero".into(),
    };
    let err = files.load().unwrap_err().to_string();
    assert!(err.contains("--tls-key") && err.contains("1 MiB"), "{err}");
}
