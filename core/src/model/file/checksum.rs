//! The model file's checksum (docs/model-file.md#the-checksum): SHA-256 over what defines a
//! model's answers, its format, its config and every member's parameter arrays, so that an
//! edit (one weight's digit, a member removed, the `members` key deleted, Δt changed) no
//! longer matches. The report and `made` are left out: they describe the model and change
//! none of its answers (a renamed report is not an edit of the model), and a reader checks the
//! report's member count against the members on its own (`integrity.rs`).
//!
//! The hash is over a canonical encoding of the values, never over the file's text, so that
//! JSON formatting (whitespace, key order, `1.0` or `1` or `1e0`, escapes) does not change it:
//! a file pretty-printed by another tool still proves it is whole. Parameters are hashed as
//! their f64 bits (the exact weights the file loads into); the config as the JSON value the
//! file holds (keys sorted, an integral number as the integer it is), not as today's
//! `ModelConfig` serializes it, so that a later version that adds a config field with a
//! default still verifies the files written before it. SHA-256, not a faster non-cryptographic
//! hash, because it is already the store's content key (one pinned crate, `sha2`) and an edit
//! made on purpose to collide must be as hard as it gets; its cost is a few ms a megabyte.

use serde_json::{Number, Value};
use sha2::{Digest, Sha256};

use crate::model::NamedArray;

/// The checksum's prefix in a file: the algorithm, so that another can follow without
/// breaking the files written before it.
pub const ALGORITHM: &str = "sha256:";

/// What starts every hashed message: a later encoding gets a new tag.
const DOMAIN: &[u8] = b"graybox.model.checksum/1\0";

/// The checksum ("sha256:" and 64 lowercase hex digits) of a file with this format, config
/// (as the JSON value written or read) and members' arrays (member 0's `params` first).
pub fn of(format: &str, config: &Value, members: &[&[NamedArray]]) -> String {
    let mut h = Sha256::new();
    h.update(DOMAIN);
    text(&mut h, format);
    value(&mut h, config);
    length(&mut h, members.len());
    for arrays in members {
        length(&mut h, arrays.len());
        for a in *arrays {
            text(&mut h, &a.name);
            length(&mut h, a.shape.len());
            for d in &a.shape {
                length(&mut h, *d);
            }
            floats(&mut h, &a.values);
        }
    }
    let digest = h.finalize();
    let mut out = String::with_capacity(ALGORITHM.len() + 64);
    out.push_str(ALGORITHM);
    for b in digest {
        out.push_str(&format!("{b:02x}"));
    }
    out
}

/// Every length is written before what it counts, so no two messages encode alike.
fn length(h: &mut Sha256, n: usize) {
    h.update((n as u64).to_le_bytes());
}

fn text(h: &mut Sha256, s: &str) {
    length(h, s.len());
    h.update(s.as_bytes());
}

/// The values' bits, a block at a time (one `update` per value costs more than the hash).
fn floats(h: &mut Sha256, values: &[f64]) {
    length(h, values.len());
    let mut block = [0u8; 8 * 512];
    for chunk in values.chunks(512) {
        for (bytes, v) in block.chunks_exact_mut(8).zip(chunk) {
            bytes.copy_from_slice(&v.to_bits().to_le_bytes());
        }
        h.update(&block[..8 * chunk.len()]);
    }
}

/// A number as its value: an integral one (written `2`, `2.0` or `2e0`) as that integer, any
/// other as its f64 bits. Each kind of value has its own tag byte (`n`, `t`, `f`, `i`, `r`,
/// `s`, `[`, `{`).
fn number(h: &mut Sha256, n: &Number) {
    let integral = (n.as_i64().map(i128::from))
        .or_else(|| n.as_u64().map(i128::from))
        .or_else(|| {
            let f = n.as_f64()?;
            (f.fract() == 0.0 && f.abs() < 2f64.powi(64)).then_some(f as i128)
        });
    match integral {
        Some(i) => {
            h.update(b"i");
            h.update(i.to_le_bytes());
        }
        None => {
            h.update(b"r");
            h.update(n.as_f64().unwrap_or(f64::NAN).to_bits().to_le_bytes());
        }
    }
}

/// A JSON value in canonical form, walked with a stack of its own: a config's depth is bounded
/// by JSON's parser (128) when read, but the walk does not rely on it (ARCHITECTURE.md, input
/// never sets a recursion depth).
fn value(h: &mut Sha256, v: &Value) {
    enum Next<'a> {
        Value(&'a Value),
        Key(&'a str),
    }
    let mut stack = vec![Next::Value(v)];
    while let Some(next) = stack.pop() {
        let v = match next {
            Next::Key(k) => {
                text(h, k);
                continue;
            }
            Next::Value(v) => v,
        };
        match v {
            Value::Null => h.update(b"n"),
            Value::Bool(b) => h.update(if *b { b"t" } else { b"f" }),
            Value::Number(n) => number(h, n),
            Value::String(s) => {
                h.update(b"s");
                text(h, s);
            }
            Value::Array(items) => {
                h.update(b"[");
                length(h, items.len());
                stack.extend(items.iter().rev().map(Next::Value));
            }
            Value::Object(map) => {
                h.update(b"{");
                length(h, map.len());
                let mut entries: Vec<_> = map.iter().collect();
                entries.sort_unstable_by(|a, b| a.0.cmp(b.0));
                for (k, v) in entries.into_iter().rev() {
                    stack.push(Next::Value(v));
                    stack.push(Next::Key(k));
                }
            }
        }
    }
}
