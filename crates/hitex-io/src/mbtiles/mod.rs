//! MBTiles 1.3: a tile store as one SQLite file of web-mercator tiles (the
//! form web-map servers, GIS tools and flight-simulator scenery tools load),
//! through `rusqlite` with its bundled SQLite.
//!
//! hitex writes the `metadata` rows the specification requires (`name`,
//! `format`) and those it recommends (`bounds`, `center`, `minzoom`,
//! `maxzoom`, `type`, `version`, `description`), its own store description
//! as the row `hitex` (the `metadata.json` of the folder form), and the
//! store's elevation model in a table `hitex_files` that other readers
//! ignore. Tiles are PNG, rows counted from the south (TMS), as the
//! specification has them. A file is built under a temporary name beside
//! its destination and renamed when complete.
//!
//! An MBTiles file made by another tool (GDAL, MapTiler, mb-util, …: no
//! `hitex` row) is read as a web-mercator store too, imagery only (flat
//! ground): its extent from the `bounds` row (else from its deepest tiles),
//! its zooms from the tiles it holds, tiles PNG or JPEG of 256 or 512
//! texels (a 512-texel tile of zoom z is four maps of zoom z + 1), rows from
//! the south unless `scheme` says `xyz`. A tile the file omits (most tools
//! leave out empty ones) reads as a transparent map; the zooms the file
//! lacks, from the one tile that holds the whole extent down, are
//! box-filtered from their children in linear light, as `terrain build`
//! makes its own coarser levels.

use crate::IoError;
use crate::gst::{
    MAX_MERCATOR_ZOOM, MAX_TILE_FILE_BYTES, MERCATOR_HALF, MERCATOR_RADIUS, Profile, StoreMeta, TILE, TileSink,
    decode_tile, parse_store_meta,
};
use rusqlite::{Connection, OpenFlags, OptionalExtension, params};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

mod foreign;
#[cfg(test)]
mod tests;

pub use foreign::*;

/// The first 16 bytes of every SQLite database file.
pub const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// Whether a file's first bytes are those of an SQLite database.
pub fn is_sqlite(head: &[u8]) -> bool {
    head.starts_with(SQLITE_MAGIC)
}

/// Largest stored file (the elevation model) read back: 1 GiB.
pub const MAX_STORED_FILE_BYTES: u64 = 1 << 30;

/// An MBTiles file open for building or reading. Connections are used from
/// one thread at a time (a mutex), so that worker threads can share it.
pub struct MbTiles {
    conn: Mutex<Connection>,
    path: PathBuf,
    /// Set for a file made by another tool: how its tiles become maps.
    foreign: Option<Foreign>,
}

fn sql_err(path: &Path, e: rusqlite::Error) -> IoError {
    IoError::Format { path: path.to_path_buf(), message: format!("SQLite: {e}") }
}

fn write_err(path: &Path, e: rusqlite::Error) -> IoError {
    IoError::Write { path: path.to_path_buf(), message: format!("SQLite: {e}") }
}

impl MbTiles {
    /// A new, empty MBTiles file at `path` (replacing one there), its tables
    /// created and one transaction open until [`MbTiles::finish`].
    pub fn create(path: &Path) -> Result<Self, IoError> {
        match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(IoError::Write { path: path.to_path_buf(), message: e.to_string() });
            }
            _ => {}
        }
        let conn = Connection::open(path).map_err(|e| write_err(path, e))?;
        // the file is renamed into place only when complete: no journal needed
        conn.execute_batch(
            "PRAGMA journal_mode = OFF;
             PRAGMA synchronous = OFF;
             PRAGMA application_id = 0x4d504258;
             CREATE TABLE metadata (name TEXT NOT NULL, value TEXT);
             CREATE UNIQUE INDEX name ON metadata (name);
             CREATE TABLE tiles (zoom_level INTEGER NOT NULL, tile_column INTEGER NOT NULL,
                                 tile_row INTEGER NOT NULL, tile_data BLOB NOT NULL);
             CREATE UNIQUE INDEX tile_index ON tiles (zoom_level, tile_column, tile_row);
             CREATE TABLE hitex_files (name TEXT PRIMARY KEY, data BLOB NOT NULL);
             BEGIN;",
        )
        .map_err(|e| write_err(path, e))?;
        Ok(Self { conn: Mutex::new(conn), path: path.to_path_buf(), foreign: None })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Connection> {
        // a worker that panicked while holding the connection left it usable
        self.conn.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Writes the `metadata` rows of `meta` (a web-mercator store), `name` its `name` row.
    pub fn write_metadata(&self, meta: &StoreMeta, name: &str) -> Result<(), IoError> {
        let Some([w, s, e, n]) = meta.lon_lat_bounds() else {
            return Err(IoError::Write {
                path: self.path.clone(),
                message: "MBTiles holds web-mercator tiles; this store is a local pyramid".into(),
            });
        };
        let json = serde_json::to_string(meta)
            .map_err(|e| IoError::Write { path: self.path.clone(), message: e.to_string() })?;
        let (minzoom, maxzoom) = (meta.zoom(0), meta.zoom(meta.levels - 1));
        let rows = [
            ("name", name.to_string()),
            ("format", "png".into()),
            ("bounds", format!("{w:.7},{s:.7},{e:.7},{n:.7}")),
            ("center", format!("{:.7},{:.7},{}", (w + e) / 2.0, (s + n) / 2.0, (minzoom + maxzoom) / 2)),
            ("minzoom", minzoom.to_string()),
            ("maxzoom", maxzoom.to_string()),
            ("type", "baselayer".into()),
            ("version", "1".into()),
            ("description", format!("hitex geospecific texture pyramid of {}", meta.source)),
            ("hitex", json),
        ];
        let conn = self.lock();
        for (k, v) in rows {
            conn.execute("INSERT OR REPLACE INTO metadata (name, value) VALUES (?1, ?2)", params![k, v])
                .map_err(|e| write_err(&self.path, e))?;
        }
        Ok(())
    }

    /// Stores a file beside the tiles (the store's elevation model).
    pub fn put_file(&self, name: &str, data: &[u8]) -> Result<(), IoError> {
        self.lock()
            .execute("INSERT OR REPLACE INTO hitex_files (name, data) VALUES (?1, ?2)", params![name, data])
            .map_err(|e| write_err(&self.path, e))?;
        Ok(())
    }

    /// Commits the build's transaction and closes the file.
    pub fn finish(self) -> Result<(), IoError> {
        let conn = self.conn.into_inner().unwrap_or_else(|p| p.into_inner());
        conn.execute_batch("COMMIT;").map_err(|e| write_err(&self.path, e))?;
        conn.close().map_err(|(_, e)| write_err(&self.path, e))
    }

    /// Opens an MBTiles file for reading: its store description, checked.
    pub fn open(path: &Path) -> Result<(Self, StoreMeta), IoError> {
        let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
        let mut head = [0u8; 16];
        {
            use std::io::Read;
            let mut f =
                std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
            let n = f.read(&mut head).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
            if !is_sqlite(&head[..n]) {
                return Err(fmt("not an SQLite database, so not an MBTiles file".into()));
            }
        }
        let conn =
            Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX)
                .map_err(|e| sql_err(path, e))?;
        let has_table = |t: &str| -> Result<bool, IoError> {
            conn.query_row("SELECT count(*) FROM sqlite_master WHERE name = ?1", params![t], |r| r.get::<_, i64>(0))
                .map(|c| c > 0)
                .map_err(|e| sql_err(path, e))
        };
        if !has_table("metadata")? || !has_table("tiles")? {
            return Err(
                fmt("an SQLite database without the tables `metadata` and `tiles`: not an MBTiles file".into()),
            );
        }
        let Some(json) = metadata_value(&conn, path, "hitex")? else {
            let (meta, foreign) = foreign_meta(&conn, path)?;
            return Ok((Self { conn: Mutex::new(conn), path: path.to_path_buf(), foreign: Some(foreign) }, meta));
        };
        let meta = parse_store_meta(&json, path)?;
        if meta.profile != Profile::Mercator {
            return Err(fmt("its store description is not of a web-mercator pyramid".into()));
        }
        match metadata_value(&conn, path, "format")?.as_deref() {
            Some("png") => {}
            other => return Err(fmt(format!("tiles of format {other:?}; hitex's stores hold png"))),
        }
        Ok((Self { conn: Mutex::new(conn), path: path.to_path_buf(), foreign: None }, meta))
    }

    /// Whether the file was made by another tool (it has no `hitex` row):
    /// imagery only, read as the module documentation says.
    pub fn is_foreign(&self) -> bool {
        self.foreign.is_some()
    }

    /// The stored bytes of the tile at `zoom`, `column`, TMS `row`, if any.
    pub fn tile_bytes(&self, zoom: u32, column: u32, row: u32) -> Result<Option<Vec<u8>>, IoError> {
        let conn = self.lock();
        let len: Option<i64> = conn
            .query_row(
                "SELECT length(tile_data) FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                params![zoom, column, row],
                |r| r.get(0),
            )
            .optional()
            .map_err(|e| sql_err(&self.path, e))?;
        let Some(len) = len else { return Ok(None) };
        if len < 0 || len as u64 > MAX_TILE_FILE_BYTES {
            return Err(IoError::Format {
                path: self.path.clone(),
                message: format!(
                    "tile {zoom}/{column}/{row} of {len} bytes; a map never needs more than {MAX_TILE_FILE_BYTES}"
                ),
            });
        }
        conn.query_row(
            "SELECT tile_data FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
            params![zoom, column, row],
            |r| r.get(0),
        )
        .optional()
        .map_err(|e| sql_err(&self.path, e))
    }

    /// Map (x, y-from-north) of level `z` of `meta` as RGBA8.
    pub fn read_map(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
        if let Some(f) = &self.foreign {
            return self.foreign_map(f, meta, z, x, y);
        }
        let (col, row) = (meta.global_tile(z, x, y).0, meta.tms_row(z, y));
        let zoom = meta.zoom(z);
        let name = self.path.join(format!("{zoom}/{col}/{row}.png"));
        match self.tile_bytes(zoom, col, row)? {
            Some(bytes) => decode_tile(&bytes, &name),
            None => Err(IoError::Format {
                path: self.path.clone(),
                message: format!("no tile {zoom}/{col}/{row} (zoom/column/row from the south)"),
            }),
        }
    }

    /// Map (x, y-from-north) of level `z` of a foreign file's store: cut from
    /// the file's tile, transparent where the file has none, or, at a zoom
    /// the file lacks, built from its four children.
    fn foreign_map(&self, f: &Foreign, meta: &StoreMeta, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
        let zoom = meta.zoom(z);
        if f.zooms.binary_search(&zoom).is_err() {
            // two or more zooms above the next one the file holds (each
            // summing 16 or more of its tiles): kept once built
            let keep = f.zooms.iter().find(|&&held| held > zoom).is_some_and(|&held| held - zoom >= 2);
            let lock = || f.built.lock().unwrap_or_else(|p| p.into_inner());
            if keep && let Some(m) = lock().get(&(z, x, y)) {
                return Ok(m.clone());
            }
            let out = crate::gst::parent_tile(meta, self, z, x, y)?;
            if keep {
                let mut kept = lock();
                if kept.len() < MAX_KEPT_MAPS {
                    kept.insert((z, x, y), out.clone());
                }
            }
            return Ok(out);
        }
        let (gx, gy) = meta.global_tile(z, x, y);
        let (fzoom, fx, fy) = if f.side == 2 * TILE { (zoom - 1, gx / 2, gy / 2) } else { (zoom, gx, gy) };
        let row = if f.xyz { fy } else { ((1u64 << fzoom) - 1 - fy as u64) as u32 };
        let Some(bytes) = self.tile_bytes(fzoom, fx, row)? else {
            return Ok(vec![0; (TILE * TILE * 4) as usize]);
        };
        let name = self.path.join(format!("{fzoom}/{fx}/{row}"));
        let img = crate::decode_image(&bytes, &name, hitex_core::texture::ColorSpace::Srgb)?;
        if img.width() != f.side || img.height() != f.side {
            return Err(IoError::Format {
                path: name,
                message: format!(
                    "tile of {}x{} texels; the file's tiles are {}x{}",
                    img.width(),
                    img.height(),
                    f.side,
                    f.side
                ),
            });
        }
        let all = img.bytes();
        if f.side == TILE {
            return Ok(all.to_vec());
        }
        // the quarter of the 512-texel tile that is this map
        let (ox, oy) = ((gx % 2 * TILE) as usize, (gy % 2 * TILE) as usize);
        let (t, s) = (TILE as usize, f.side as usize);
        let mut out = Vec::with_capacity(t * t * 4);
        for j in 0..t {
            let i = ((oy + j) * s + ox) * 4;
            out.extend_from_slice(&all[i..i + t * 4]);
        }
        Ok(out)
    }

    /// A file stored beside the tiles, if there is one of that name.
    pub fn file(&self, name: &str) -> Result<Option<Vec<u8>>, IoError> {
        let conn = self.lock();
        let has_files = conn
            .query_row("SELECT count(*) FROM sqlite_master WHERE name = 'hitex_files'", [], |r| r.get::<_, i64>(0))
            .map_err(|e| sql_err(&self.path, e))?;
        if has_files == 0 {
            return Ok(None);
        }
        let len: Option<i64> = conn
            .query_row("SELECT length(data) FROM hitex_files WHERE name = ?1", params![name], |r| r.get(0))
            .optional()
            .map_err(|e| sql_err(&self.path, e))?;
        match len {
            None => Ok(None),
            Some(l) if l < 0 || l as u64 > MAX_STORED_FILE_BYTES => Err(IoError::Format {
                path: self.path.join(name),
                message: format!("stored file of {l} bytes, beyond {MAX_STORED_FILE_BYTES}"),
            }),
            Some(_) => conn
                .query_row("SELECT data FROM hitex_files WHERE name = ?1", params![name], |r| r.get(0))
                .optional()
                .map_err(|e| sql_err(&self.path, e)),
        }
    }

    /// The names of the files stored beside the tiles.
    pub fn file_names(&self) -> Result<Vec<String>, IoError> {
        let conn = self.lock();
        let has_files = conn
            .query_row("SELECT count(*) FROM sqlite_master WHERE name = 'hitex_files'", [], |r| r.get::<_, i64>(0))
            .map_err(|e| sql_err(&self.path, e))?;
        if has_files == 0 {
            return Ok(Vec::new());
        }
        let mut st = conn.prepare("SELECT name FROM hitex_files ORDER BY name").map_err(|e| sql_err(&self.path, e))?;
        let names = st
            .query_map([], |r| r.get::<_, String>(0))
            .map_err(|e| sql_err(&self.path, e))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| sql_err(&self.path, e))?;
        Ok(names)
    }

    /// Tiles in the file.
    pub fn tile_count(&self) -> Result<u64, IoError> {
        self.lock()
            .query_row("SELECT count(*) FROM tiles", [], |r| r.get::<_, i64>(0))
            .map(|c| c.max(0) as u64)
            .map_err(|e| sql_err(&self.path, e))
    }
}

impl TileSink for MbTiles {
    fn put(&self, meta: &StoreMeta, z: u32, x: u32, y: u32, png: &[u8]) -> Result<(), IoError> {
        let (col, row) = (meta.global_tile(z, x, y).0, meta.tms_row(z, y));
        self.lock()
            .execute(
                "INSERT OR REPLACE INTO tiles (zoom_level, tile_column, tile_row, tile_data) VALUES (?1, ?2, ?3, ?4)",
                params![meta.zoom(z), col, row, png],
            )
            .map_err(|e| write_err(&self.path, e))?;
        Ok(())
    }
    fn get(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
        self.read_map(meta, z, x, y)
    }
    fn has(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> bool {
        let (col, row) = (meta.global_tile(z, x, y).0, meta.tms_row(z, y));
        self.lock()
            .query_row(
                "SELECT 1 FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                params![meta.zoom(z), col, row],
                |_| Ok(()),
            )
            .optional()
            .is_ok_and(|r| r.is_some())
    }
}

/// Builds the web-mercator pyramid of `src` into one MBTiles file `out`,
/// with `files` (name, bytes) stored beside the tiles; written under a
/// temporary name and renamed when complete. A file at `out` that is not an
/// SQLite database is refused, not replaced.
pub fn build_mbtiles(
    src: &dyn crate::gst::TileSource,
    meta: &StoreMeta,
    out: &Path,
    files: &[(String, Vec<u8>)],
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<crate::gst::BuildReport, IoError> {
    write_whole(out, meta, files, |db| {
        crate::gst::build_into(src, meta, db, crate::gst::BuildOptions::default(), progress)
    })
}

/// Packs a finished web-mercator folder store (e.g. one built by shards)
/// into one MBTiles file `out`, its maps copied byte for byte with the DEM
/// it keeps; returns the tiles written.
pub fn pack_folder(store: &Path, out: &Path, progress: &(dyn Fn(u64, u64) + Sync)) -> Result<u64, IoError> {
    let meta = crate::gst::open_store(store)?;
    if meta.profile != Profile::Mercator {
        return Err(IoError::Format {
            path: store.join("metadata.json"),
            message: "a local pyramid; MBTiles holds web-mercator tiles (build it with --profile mercator)".into(),
        });
    }
    let mut files = Vec::new();
    if let Some(p) = crate::gst::stored_dem(store) {
        let bytes = std::fs::read(&p).map_err(|source| IoError::Read { path: p.clone(), source })?;
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("dem.tif").to_string();
        files.push((name, bytes));
    }
    let total = meta.total_tiles();
    write_whole(out, &meta, &files, |db| {
        let mut done = 0u64;
        for z in 0..meta.levels {
            for (x, y) in meta.data_maps(z) {
                let path = meta.tile_path(store, z, x, y);
                let len =
                    std::fs::metadata(&path).map_err(|source| IoError::Read { path: path.clone(), source })?.len();
                if len > MAX_TILE_FILE_BYTES {
                    return Err(IoError::Format {
                        path,
                        message: format!("map file of {len} bytes, beyond {MAX_TILE_FILE_BYTES}"),
                    });
                }
                let bytes = std::fs::read(&path).map_err(|source| IoError::Read { path: path.clone(), source })?;
                // a map that does not decode is not packed
                decode_tile(&bytes, &path)?;
                db.put(&meta, z, x, y, &bytes)?;
                done += 1;
                progress(done, total);
            }
        }
        Ok(done)
    })
}

/// Writes an MBTiles file whole: `fill` stores the tiles into a file under a
/// temporary name beside `out`, then the files, the metadata, and the rename.
fn write_whole<T>(
    out: &Path,
    meta: &StoreMeta,
    files: &[(String, Vec<u8>)],
    fill: impl FnOnce(&MbTiles) -> Result<T, IoError>,
) -> Result<T, IoError> {
    let dest = |m: String| IoError::Destination { path: out.to_path_buf(), message: m };
    if out.is_dir() {
        return Err(dest("a folder: an MBTiles store is one file (give a name ending in .mbtiles)".into()));
    }
    if out.exists() {
        use std::io::Read;
        let mut head = [0u8; 16];
        let n = std::fs::File::open(out).and_then(|mut f| f.read(&mut head)).unwrap_or(0);
        if !is_sqlite(&head[..n]) {
            return Err(dest("exists and is not an MBTiles file; hitex does not replace it".into()));
        }
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(dest(format!("its folder {} does not exist", dir.display())));
    }
    let name = out.file_name().and_then(|n| n.to_str()).unwrap_or("store.mbtiles");
    let tmp = dir.join(format!(".{name}.partial-{}", std::process::id()));
    let result = (|| {
        let db = MbTiles::create(&tmp)?;
        let value = fill(&db)?;
        for (n, data) in files {
            db.put_file(n, data)?;
        }
        let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("hitex");
        db.write_metadata(meta, stem)?;
        db.finish()?;
        Ok(value)
    })();
    match result {
        Ok(value) => {
            std::fs::rename(&tmp, out)
                .map_err(|e| IoError::Write { path: out.to_path_buf(), message: e.to_string() })?;
            Ok(value)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}
