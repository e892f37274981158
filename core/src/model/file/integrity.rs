//! A model file proves it is whole (docs/model-file.md): its member count is one graybox
//! writes and agrees with its report, and its checksum (`checksum.rs`), which every write adds,
//! matches its contents. A file from before checksums loads with a warning.

use serde::{Deserialize, Serialize};

use super::{FORMAT_ENSEMBLE, ModelFile, checksum};
use crate::error::{Error, Result};
use crate::model::NamedArray;
use crate::records::Warning;

/// The most members an ensemble may have, in training (`train::setup`) and in a file a reader
/// accepts: each costs a model's training and inference, and a file over it was not written by
/// graybox.
pub const MAX_MEMBERS: usize = 32;

/// The code of the warning a file without a checksum (written before files carried one) is
/// read with.
pub const UNCHECKED: &str = "model_file_unchecked";

/// What `to_bytes` writes: the file and its checksum.
#[derive(Serialize)]
struct Sealed<'a> {
    checksum: &'a str,
    #[serde(flatten)]
    file: &'a ModelFile,
}

/// The parts of a file's text its checksum is checked against, read apart from the typed
/// file: the config as the JSON value the file holds (`checksum.rs` says why).
#[derive(Deserialize)]
struct Seal {
    #[serde(default)]
    checksum: Option<String>,
    config: serde_json::Value,
}

impl ModelFile {
    /// Member 0's arrays, then the other members', in order.
    fn member_arrays(&self) -> Vec<&[NamedArray]> {
        std::iter::once(self.params.as_slice())
            .chain(self.members.iter().map(Vec::as_slice))
            .collect()
    }

    /// The warning a reader passes on (the service's upload response and log, the CLI's
    /// stderr, Python's `warnings`, the C library's `gbx_model_warning`) for a file that does
    /// not prove it is whole: one written before files carried a checksum. None for a file
    /// whose checksum held and for one made in memory.
    pub fn unchecked_warning(&self) -> Option<Warning> {
        self.unchecked.then(|| {
            Warning::new(
                UNCHECKED,
                Some("checksum".into()),
                "this model file has no checksum (it was written before graybox files carried \
                 one), so nothing shows that its parameters are the ones its writer wrote; it \
                 is served as it is. A file written by this graybox carries one"
                    .into(),
            )
        })
    }

    /// Whether the file's members are a model graybox could have written: at most
    /// [`MAX_MEMBERS`], an ensemble's format with its `members` (deleting them must not leave
    /// one model that answers with no spread, as if certain), and as many as its report lists.
    /// Checked with or without a checksum: a file from before checksums is held to it too.
    pub(super) fn check_members(&self) -> Result<()> {
        let count = self.member_count();
        if count > MAX_MEMBERS {
            return Err(Error::invalid(
                "members",
                format!(
                    "the file has {count} members; an ensemble has at most {MAX_MEMBERS} (the \
                     training limit), so this file was not written by graybox"
                ),
            ));
        }
        if let Some(report) = &self.report {
            let listed = report.ensemble.as_ref().map_or(1, |e| e.members.len());
            if listed != count {
                return Err(Error::invalid(
                    "members",
                    format!(
                        "the file has {count} member(s) but its report lists {listed}: members \
                         were removed or added after it was written"
                    ),
                ));
            }
        }
        if self.format == FORMAT_ENSEMBLE && count < 2 {
            return Err(Error::invalid(
                "members",
                format!(
                    "a {FORMAT_ENSEMBLE} file is an ensemble, but this one has no `members` \
                     beside `params`: served as one model it would answer with no spread, as \
                     if certain"
                ),
            ));
        }
        Ok(())
    }

    /// The checksum this file's contents give, with its config as `config` (the value written,
    /// or the one read).
    fn checksum(&self, config: &serde_json::Value) -> String {
        checksum::of(&self.format, config, &self.member_arrays())
    }

    /// Checks the file's checksum against its text's (`bytes`): a mismatch is refused naming
    /// `checksum`; a file without one is marked unchecked.
    pub(super) fn check_seal(&mut self, bytes: &[u8]) -> Result<()> {
        let seal: Seal =
            serde_json::from_slice(bytes).map_err(|e| Error::corrupt("model file", e))?;
        let Some(written) = seal.checksum else {
            self.unchecked = true;
            return Ok(());
        };
        if !written.starts_with(checksum::ALGORITHM) {
            return Err(Error::invalid(
                "checksum",
                format!(
                    "'{}' is not a checksum this graybox can verify (it writes {}…)",
                    written.chars().take(80).collect::<String>(),
                    checksum::ALGORITHM
                ),
            ));
        }
        let found = self.checksum(&seal.config);
        if written != found {
            return Err(Error::invalid(
                "checksum",
                format!(
                    "the file's parameters, members or config are not the ones it was written \
                     with (its checksum is {}…, its contents give {}…): it was edited or \
                     damaged after it was written, so it is not served",
                    written.chars().take(19).collect::<String>(),
                    &found[..19]
                ),
            ));
        }
        Ok(())
    }

    /// The file's bytes with a checksum of what they hold.
    pub(super) fn sealed(&self) -> Vec<u8> {
        let config = serde_json::to_value(&self.config).expect("configs serialize");
        let sealed = Sealed {
            checksum: &self.checksum(&config),
            file: self,
        };
        serde_json::to_vec(&sealed).expect("model files serialize")
    }
}
