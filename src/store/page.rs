//! Pages of a list bounded by their bytes as well as their count: rows whose documents are
//! large (a model's spec embeds its template) fill a page before its count does.

/// The next page of `$table` (newest first, `seq < $before`) as records `$T`: at most
/// `$limit` rows and [`super::PAGE_BYTES`] by the byte length `$size` (an SQL expression) of each,
/// at least one; and whether rows remain after them. The lengths are read first, then only the
/// rows that fit. (A macro: it runs on either backend's pool, in `on_db!`.)
macro_rules! page {
    ($pool:expr, $D:ty, $T:ty, $table:literal, $columns:expr, $size:literal, $before:expr, $limit:expr) => {{
        let (before, limit): (i64, i64) = ($before, $limit);
        // BIGINT: Postgres's length() is a 4-byte integer, which does not decode as i64.
        let sizes: Vec<i64> = sqlx::query_scalar(concat!(
            "SELECT CAST(",
            $size,
            " AS BIGINT) FROM ",
            $table,
            " WHERE seq < $1 ORDER BY seq DESC LIMIT $2"
        ))
        .bind(before)
        .bind(limit)
        .fetch_all($pool)
        .await?;
        let (fit, more) = $crate::store::page::fitting(&sizes, limit);
        let rows = sqlx::query($crate::store::dialect::sql::<$D>(
            concat!(
                "SELECT {COLUMNS} FROM ",
                $table,
                " WHERE seq < $1 ORDER BY seq DESC LIMIT $2"
            ),
            $columns,
        ))
        .bind(before)
        .bind(fit)
        .fetch_all($pool)
        .await?;
        let rows: Vec<$T> = rows
            .iter()
            .map($crate::store::row)
            .collect::<$crate::error::Result<_>>()?;
        (rows, more)
    }};
}

/// How many of the next `limit` rows, of these byte lengths, fit in [`super::PAGE_BYTES`], at least
/// one; and whether rows remain after them.
pub(super) fn fitting(sizes: &[i64], limit: i64) -> (i64, bool) {
    let mut total = 0i64;
    let mut fit = 0i64;
    for s in sizes {
        if fit > 0 && total.saturating_add(*s) > super::PAGE_BYTES {
            break;
        }
        total = total.saturating_add(*s);
        fit += 1;
    }
    let more = (fit as usize) < sizes.len() || sizes.len() as i64 == limit;
    (fit, more)
}
