//! What a Parquet column chunk's pages claim they decompress to, read from their headers
//! before the decoder sees them: the decoder allocates each page's claimed size (up to 2 GiB
//! from a few bytes), so an upload's memory bound must count the claims, not the metadata's
//! totals, which a crafted file may understate.
//!
//! A page header is a Thrift struct in the compact protocol; its field 2 is the page's
//! uncompressed size and field 3 its compressed size (the bytes that follow the header).
//! Every other field is skipped by its type, nested structs and lists to a bounded depth.

use crate::error::{Error, Result};

/// Deeper than any page header's nesting (a statistics struct inside a data page header).
const MAX_DEPTH: usize = 8;

/// The sum of the uncompressed sizes the pages in `chunk` (the column chunk's bytes) claim.
pub fn claimed(chunk: &[u8]) -> Result<u64> {
    let (mut at, mut total) = (0usize, 0u64);
    while at < chunk.len() {
        let mut r = Reader { bytes: chunk, at };
        let (uncompressed, compressed) = r.page_header()?;
        total = total.saturating_add(uncompressed);
        at = r.at.saturating_add(compressed as usize);
    }
    Ok(total)
}

fn malformed() -> Error {
    Error::invalid("log", "unreadable Parquet: a malformed page header")
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8> {
        let b = *self.bytes.get(self.at).ok_or_else(malformed)?;
        self.at += 1;
        Ok(b)
    }

    fn varint(&mut self) -> Result<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.byte()?;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(malformed())
    }

    fn zigzag(&mut self) -> Result<i64> {
        let v = self.varint()?;
        Ok((v >> 1) as i64 ^ -((v & 1) as i64))
    }

    fn skip_bytes(&mut self, n: u64) -> Result<()> {
        let end = (self.at as u64).checked_add(n).ok_or_else(malformed)?;
        if end > self.bytes.len() as u64 {
            return Err(malformed());
        }
        self.at = end as usize;
        Ok(())
    }

    /// A page header's (uncompressed, compressed) sizes, the reader left after it.
    fn page_header(&mut self) -> Result<(u64, u64)> {
        let (mut uncompressed, mut compressed) = (None, None);
        let mut id = 0i64;
        loop {
            let head = self.byte()?;
            let ty = head & 0x0f;
            if ty == 0 {
                break;
            }
            id = match head >> 4 {
                0 => self.zigzag()?,
                delta => id + i64::from(delta),
            };
            match (id, ty) {
                (2, 5) => uncompressed = Some(self.zigzag()?),
                (3, 5) => compressed = Some(self.zigzag()?),
                _ => self.skip(ty, 0)?,
            }
        }
        match (uncompressed, compressed) {
            (Some(u), Some(c)) if u >= 0 && c >= 0 => Ok((u as u64, c as u64)),
            _ => Err(malformed()),
        }
    }

    /// Skips one value of compact type `ty`.
    fn skip(&mut self, ty: u8, depth: usize) -> Result<()> {
        if depth > MAX_DEPTH {
            return Err(malformed());
        }
        match ty {
            1 | 2 => Ok(()),
            3 => self.skip_bytes(1),
            4..=6 => self.varint().map(drop),
            7 => self.skip_bytes(8),
            8 => {
                let n = self.varint()?;
                self.skip_bytes(n)
            }
            9 | 10 => {
                let head = self.byte()?;
                let n = match head >> 4 {
                    15 => self.varint()?,
                    n => u64::from(n),
                };
                self.items(head & 0x0f, n, depth)
            }
            11 => {
                let n = self.varint()?;
                if n == 0 {
                    return Ok(());
                }
                let types = self.byte()?;
                self.fits(n)?;
                for _ in 0..n {
                    self.element(types >> 4, depth)?;
                    self.element(types & 0x0f, depth)?;
                }
                Ok(())
            }
            12 => loop {
                let head = self.byte()?;
                if head & 0x0f == 0 {
                    return Ok(());
                }
                if head >> 4 == 0 {
                    self.zigzag()?;
                }
                self.skip(head & 0x0f, depth + 1)?;
            },
            _ => Err(malformed()),
        }
    }

    /// A list's `n` items of type `ty`.
    fn items(&mut self, ty: u8, n: u64, depth: usize) -> Result<()> {
        self.fits(n)?;
        (0..n).try_for_each(|_| self.element(ty, depth))
    }

    /// A container's element: a boolean is a byte there, and every element takes at least
    /// one byte, so `fits` bounds a container's loop by the bytes left.
    fn element(&mut self, ty: u8, depth: usize) -> Result<()> {
        match ty {
            1 | 2 => self.skip_bytes(1),
            _ => self.skip(ty, depth + 1),
        }
    }

    fn fits(&self, n: u64) -> Result<()> {
        if n > (self.bytes.len() - self.at) as u64 {
            return Err(malformed());
        }
        Ok(())
    }
}
