//! MBTiles 1.3 archives (SQLite through rusqlite): the `metadata` table (name, format, bounds,
//! center, minzoom, maxzoom, and the rest of the export's metadata) and the `tiles` table with
//! TMS rows (`tile_row = 2^z − 1 − y`). Written under a temporary name and renamed when the last
//! tile is committed; parts of a sharded export are joined by [`merge`].

use std::path::{Path, PathBuf};

use rusqlite::{params, Connection, OpenFlags};

use super::{io_error, temporary_path, ArchiveError};

fn sql(path: &Path) -> impl Fn(rusqlite::Error) -> ArchiveError + '_ {
    move |e| ArchiveError::Format(format!("{}: SQLite: {e}", path.display()))
}

/// The TMS row of XYZ row `y` at zoom `z` (MBTiles counts rows from the south).
pub fn tms_row(z: u8, y: u32) -> u32 {
    ((1u64 << z) - 1 - u64::from(y)) as u32
}

const SCHEMA: &str = "
    PRAGMA journal_mode = OFF;
    PRAGMA synchronous = OFF;
    CREATE TABLE metadata (name TEXT NOT NULL, value TEXT);
    CREATE UNIQUE INDEX metadata_name ON metadata (name);
    CREATE TABLE tiles (zoom_level INTEGER NOT NULL, tile_column INTEGER NOT NULL,
                        tile_row INTEGER NOT NULL, tile_data BLOB NOT NULL);
    CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row);
";

/// An MBTiles archive being written under a temporary name.
pub struct Writer {
    conn: Connection,
    tmp: PathBuf,
    output: PathBuf,
}

impl Writer {
    /// Creates the archive's tables and `metadata` (name → value, in the given order) under a
    /// temporary name beside `output`.
    pub fn create(output: &Path, metadata: &[(String, String)]) -> Result<Writer, ArchiveError> {
        let tmp = temporary_path(output);
        let _ = std::fs::remove_file(&tmp);
        let conn = Connection::open(&tmp).map_err(sql(output))?;
        let w = Writer {
            conn,
            tmp,
            output: output.to_path_buf(),
        };
        w.conn.execute_batch(SCHEMA).map_err(sql(output))?;
        w.conn.execute_batch("BEGIN").map_err(sql(output))?;
        for (k, v) in metadata {
            w.conn
                .execute(
                    "INSERT INTO metadata (name, value) VALUES (?1, ?2)",
                    params![k, v],
                )
                .map_err(sql(output))?;
        }
        Ok(w)
    }

    /// Adds tile `z/x/y` (XYZ coordinates; stored with the TMS row).
    pub fn add(&mut self, z: u8, x: u32, y: u32, bytes: &[u8]) -> Result<(), ArchiveError> {
        self.conn
            .prepare_cached(
                "INSERT INTO tiles (zoom_level, tile_column, tile_row, tile_data) \
                 VALUES (?1, ?2, ?3, ?4)",
            )
            .and_then(|mut s| s.execute(params![z, x, tms_row(z, y), bytes]))
            .map_err(sql(&self.output))?;
        Ok(())
    }

    /// Commits, closes and renames the archive to its name; returns its size.
    pub fn finish(mut self) -> Result<u64, ArchiveError> {
        let out = self.output.clone();
        self.conn.execute_batch("COMMIT").map_err(sql(&out))?;
        // Closed (and its file complete) before the rename.
        let conn = std::mem::replace(
            &mut self.conn,
            Connection::open_in_memory().map_err(sql(&out))?,
        );
        conn.close().map_err(|(_, e)| sql(&out)(e))?;
        std::fs::rename(&self.tmp, &out).map_err(io_error(&out))?;
        Ok(std::fs::metadata(&out).map_err(io_error(&out))?.len())
    }
}

impl Drop for Writer {
    fn drop(&mut self) {
        // Unfinished (an error on the way): no partial archive is left behind. After `finish`
        // the temporary name no longer exists.
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// The `metadata` table of an archive.
pub fn read_metadata(path: &Path) -> Result<Vec<(String, String)>, ArchiveError> {
    let conn =
        Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(sql(path))?;
    let mut st = conn
        .prepare("SELECT name, value FROM metadata ORDER BY rowid")
        .map_err(sql(path))?;
    let rows = st
        .query_map([], |r| Ok((r.get(0)?, r.get::<_, Option<String>>(1)?)))
        .map_err(sql(path))?;
    let mut out = Vec::new();
    for row in rows {
        let (k, v) = row.map_err(sql(path))?;
        out.push((k, v.unwrap_or_default()));
    }
    Ok(out)
}

/// Joins the parts of a sharded export into `output`: their metadata must be equal and no tile
/// may be in two parts. Returns (tiles, bytes of the archive).
pub fn merge(parts: &[PathBuf], output: &Path) -> Result<(u64, u64), ArchiveError> {
    let first = parts
        .first()
        .ok_or_else(|| ArchiveError::Format("export merge: no parts given".into()))?;
    let metadata = read_metadata(first)?;
    for p in &parts[1..] {
        if read_metadata(p)? != metadata {
            return Err(ArchiveError::Format(format!(
                "{} and {} are parts of different exports (their metadata differ)",
                first.display(),
                p.display()
            )));
        }
    }
    let w = Writer::create(output, &metadata)?;
    let mut tiles = 0u64;
    for (i, p) in parts.iter().enumerate() {
        let path = p
            .to_str()
            .ok_or_else(|| ArchiveError::Format(format!("{}: path is not UTF-8", p.display())))?;
        let alias = format!("part{i}");
        w.conn
            .execute(&format!("ATTACH DATABASE ?1 AS {alias}"), params![path])
            .map_err(sql(p))?;
        let added = w
            .conn
            .execute(
                &format!("INSERT INTO tiles SELECT zoom_level, tile_column, tile_row, tile_data FROM {alias}.tiles"),
                [],
            )
            .map_err(|e| match e {
                rusqlite::Error::SqliteFailure(f, _)
                    if f.code == rusqlite::ErrorCode::ConstraintViolation =>
                {
                    ArchiveError::Format(format!(
                        "{}: a tile of this part is also in an earlier part",
                        p.display()
                    ))
                }
                e => sql(p)(e),
            })?;
        tiles += added as u64;
        w.conn
            .execute_batch(&format!("COMMIT; DETACH DATABASE {alias}; BEGIN"))
            .map_err(sql(p))?;
    }
    let size = w.finish()?;
    Ok((tiles, size))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tms_rows_count_from_the_south() {
        assert_eq!(tms_row(0, 0), 0);
        assert_eq!(tms_row(1, 0), 1);
        assert_eq!(tms_row(12, 1512), 4095 - 1512);
    }

    fn part(dir: &Path, name: &str, tiles: &[(u8, u32, u32)], label: &str) -> PathBuf {
        let p = dir.join(name);
        let meta = vec![("name".to_string(), label.to_string())];
        let mut w = Writer::create(&p, &meta).unwrap();
        for &(z, x, y) in tiles {
            w.add(z, x, y, format!("{z}/{x}/{y}").as_bytes()).unwrap();
        }
        w.finish().unwrap();
        p
    }

    #[test]
    fn parts_merge_and_overlaps_or_foreign_parts_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let a = part(dir.path(), "a.mbtiles", &[(0, 0, 0), (1, 0, 0)], "w");
        let b = part(dir.path(), "b.mbtiles", &[(1, 1, 0), (1, 1, 1)], "w");
        let out = dir.path().join("all.mbtiles");
        let (n, _) = merge(&[a.clone(), b], &out).unwrap();
        assert_eq!(n, 4);
        let conn = Connection::open(&out).unwrap();
        let data: Vec<u8> = conn
            .query_row(
                "SELECT tile_data FROM tiles WHERE zoom_level=1 AND tile_column=1 AND tile_row=0",
                [],
                |r| r.get(0),
            )
            .unwrap();
        assert_eq!(data, b"1/1/1");
        assert_eq!(
            read_metadata(&out).unwrap(),
            vec![("name".into(), "w".into())]
        );

        let c = part(dir.path(), "c.mbtiles", &[(1, 0, 0)], "w");
        let out2 = dir.path().join("bad.mbtiles");
        let err = merge(&[a.clone(), c], &out2).unwrap_err().to_string();
        assert!(err.contains("also in an earlier part"), "{err}");
        assert!(!out2.exists());
        let d = part(dir.path(), "d.mbtiles", &[(2, 0, 0)], "other");
        let err = merge(&[a, d], &out2).unwrap_err().to_string();
        assert!(err.contains("different exports"), "{err}");
        assert!(!out2.exists());
    }
}
