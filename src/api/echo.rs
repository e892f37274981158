//! Caller text that goes back to the caller. Error messages quote what was sent (an unknown
//! name, a value that is not a number) and a field can be a key the caller chose, so without
//! a bound a 200 MB name comes back as a 200 MB error body — and over gRPC as a status
//! header no client accepts. Both error mappings (`rest/error.rs`, `grpc/convert.rs`) cut
//! here, whichever message made the error.

/// The most of an error message a response carries (bytes, before the note).
pub const MESSAGE_LIMIT: usize = 2048;

/// The most of a REST error's `field`: a path into the request, short unless the caller
/// chose a key, and small enough that message and field together stay under 4 KiB.
pub const FIELD_LIMIT: usize = 256;

/// `text` cut to at most `limit` bytes on a character boundary, with a note of how many
/// bytes were left off so that a reader knows it is not the whole.
pub fn bounded(mut text: String, limit: usize) -> String {
    if text.len() <= limit {
        return text;
    }
    let end = text.floor_char_boundary(limit);
    let more = text.len() - end;
    text.truncate(end);
    text.push_str(&format!("… ({more} more bytes)"));
    text
}
