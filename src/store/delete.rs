//! Deleting a row by its id, the same way for every table that has a delete.

/// Deletes the row of `$table` with id `$id` in a write transaction on `$pool`, and returns
/// from the calling operation: NotFound when there is no such row; with `users`, an SQL count
/// of the queued or running jobs that use it (`$1` the id), Conflict while it is used. With
/// `blob_key`, the value is the deleted row's object key (for the caller to unreference once
/// the deletion is committed); without, `()`. (A macro: it runs on either backend's pool, in
/// `on_db!`.)
macro_rules! delete_row {
    ($pool:expr, $table:literal, $what:literal, $id:expr $(, users = $users:literal)?) => {{
        let _: Option<String> = delete_row!(@delete $pool, $table, $what, $id, "NULL" $(, $users)?);
        Ok(())
    }};
    ($pool:expr, $table:literal, $what:literal, $id:expr, blob_key $(, users = $users:literal)?) => {{
        Ok::<Option<String>, Error>(delete_row!(@delete $pool, $table, $what, $id, "blob_key" $(, $users)?))
    }};
    (@delete $pool:expr, $table:literal, $what:literal, $id:expr, $returning:literal $(, $users:literal)?) => {{
        let id: &str = $id;
        if !$crate::store::could_be_id(id) {
            return Err(Error::NotFound(format!(concat!($what, " {}"), id.escape_debug())));
        }
        let mut tx = $crate::store::dialect::begin_write($pool).await?;
        $(
            let users: i64 = sqlx::query_scalar($users).bind(id).fetch_one(&mut *tx).await?;
            if users > 0 {
                return Err(Error::Conflict(format!(
                    concat!($what, " {} is used by {} queued or running job(s)"),
                    id, users
                )));
            }
        )?
        let deleted: Option<Option<String>> = sqlx::query_scalar(concat!(
            "DELETE FROM ", $table, " WHERE id = $1 RETURNING ", $returning
        ))
        .bind(id)
        .fetch_optional(&mut *tx)
        .await?;
        let Some(key) = deleted else {
            return Err(Error::NotFound(format!(concat!($what, " {}"), id)));
        };
        tx.commit().await?;
        key
    }};
}
