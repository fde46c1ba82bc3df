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

/// Most maps of a zoom a foreign file holds within its extent from which
/// hitex builds the coarser zooms above it that the file lacks (each built
/// map reads 4^d of them, d levels down; 4,096 keeps the level-0 map to a
/// few seconds of decoding).
pub const MAX_FOREIGN_BUILD_TILES: u64 = 4096;

/// Most built maps kept once built (64 MiB); maps past it are built again
/// when asked for (the resident-map cache keeps what a flight uses).
const MAX_KEPT_MAPS: usize = 256;

/// How the tiles of an MBTiles file made by another tool become the
/// store's maps (see the module documentation).
#[derive(Debug)]
struct Foreign {
    /// The file's tile side: 256, or 512 (file zoom z is store zoom z + 1).
    side: u32,
    /// Rows counted from the north (`scheme` = `xyz`), not from the south.
    xyz: bool,
    /// The store zooms the file holds tiles of, ascending: maps of the
    /// others are built from their children.
    zooms: Vec<u32>,
    /// Built maps two or more levels above the file's tiles (each summing
    /// 16 or more of them), kept once built.
    built: Mutex<BuiltMaps>,
}

/// Maps built from their children, by level, column and row.
type BuiltMaps = HashMap<(u32, u32, u32), Vec<u8>>;

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

fn metadata_value(conn: &Connection, path: &Path, key: &str) -> Result<Option<String>, IoError> {
    conn.query_row("SELECT value FROM metadata WHERE name = ?1", params![key], |r| r.get::<_, Option<String>>(0))
        .optional()
        .map(Option::flatten)
        .map_err(|e| sql_err(path, e))
}

/// Web-mercator metres of a longitude and latitude in degrees (latitudes
/// past the projection's ±85.05° clamped to it).
fn mercator_metres(lon: f64, lat: f64) -> (f64, f64) {
    let lim = (MERCATOR_HALF / MERCATOR_RADIUS).sinh().atan();
    let phi = lat.to_radians().clamp(-lim, lim);
    (MERCATOR_RADIUS * lon.to_radians(), MERCATOR_RADIUS * (std::f64::consts::FRAC_PI_4 + phi / 2.0).tan().ln())
}

/// The store an MBTiles file made by another tool describes (see the
/// module documentation), and how its tiles become maps.
fn foreign_meta(conn: &Connection, path: &Path) -> Result<(StoreMeta, Foreign), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let value = |k: &str| metadata_value(conn, path, k);
    match value("format")?.map(|f| f.to_ascii_lowercase()).as_deref() {
        None | Some("png" | "jpg" | "jpeg") => {}
        Some("pbf" | "mvt") => {
            return Err(fmt("vector tiles (format pbf): hitex flies over raster imagery, png or jpg tiles".into()));
        }
        Some(other) => return Err(fmt(format!("tiles of format {other:?}; hitex reads png and jpg tiles"))),
    }
    let xyz = match value("scheme")?.map(|f| f.to_ascii_lowercase()).as_deref() {
        None | Some("tms") => false,
        Some("xyz") => true,
        Some(other) => return Err(fmt(format!("scheme {other:?}; MBTiles rows are tms (or xyz)"))),
    };
    let (min, max, count): (Option<i64>, Option<i64>, i64) = conn
        .query_row("SELECT min(zoom_level), max(zoom_level), count(*) FROM tiles", [], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?))
        })
        .map_err(|e| sql_err(path, e))?;
    let (Some(min), Some(max)) = (min, max) else {
        return Err(fmt("an MBTiles file that holds no tiles".into()));
    };
    if count == 0 || min < 0 || max > MAX_MERCATOR_ZOOM as i64 {
        return Err(fmt(format!("tiles of zooms {min} to {max}; hitex reads zooms 0 to {MAX_MERCATOR_ZOOM}")));
    }
    let max = max as u32;
    // the tile side, from one of the deepest tiles
    let (col, row, bytes): (i64, i64, Vec<u8>) = conn
        .query_row(
            "SELECT tile_column, tile_row, tile_data FROM tiles WHERE zoom_level = ?1 \
             AND length(tile_data) <= ?2 LIMIT 1",
            params![max, MAX_TILE_FILE_BYTES as i64],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
        )
        .optional()
        .map_err(|e| sql_err(path, e))?
        .ok_or_else(|| fmt(format!("no tile of zoom {max} within {MAX_TILE_FILE_BYTES} bytes")))?;
    let name = path.join(format!("{max}/{col}/{row}"));
    let img = crate::decode_image(&bytes, &name, hitex_core::texture::ColorSpace::Srgb)?;
    let side = img.width();
    if img.height() != side || (side != TILE && side != 2 * TILE) {
        return Err(IoError::Format {
            path: name,
            message: format!("tile of {}x{} texels; hitex reads tiles of 256 or 512 texels a side", side, img.height()),
        });
    }
    // the extent: the bounds row, else the deepest tiles' squares
    let bounds = match value("bounds")? {
        Some(b) => {
            let v: Vec<f64> = b.split(',').map(|t| t.trim().parse().unwrap_or(f64::NAN)).collect();
            let ok = v.len() == 4
                && v.iter().all(|x| x.is_finite())
                && (-180.0..=180.0).contains(&v[0])
                && (-180.0..=180.0).contains(&v[2])
                && (-90.0..=90.0).contains(&v[1])
                && (-90.0..=90.0).contains(&v[3])
                && v[0] < v[2]
                && v[1] < v[3];
            if !ok {
                return Err(fmt(format!("metadata bounds {b:?} is not west,south,east,north in degrees")));
            }
            let ((x0, y0), (x1, y1)) = (mercator_metres(v[0], v[1]), mercator_metres(v[2], v[3]));
            [x0, y0, x1, y1]
        }
        None => {
            let (c0, c1, r0, r1): (i64, i64, i64, i64) = conn
                .query_row(
                    "SELECT min(tile_column), max(tile_column), min(tile_row), max(tile_row) FROM tiles \
                     WHERE zoom_level = ?1",
                    params![max],
                    |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)),
                )
                .map_err(|e| sql_err(path, e))?;
            let n = 1i64 << max;
            if c0 < 0 || r0 < 0 || c1 >= n || r1 >= n {
                return Err(fmt(format!("tiles of zoom {max} outside its {n}x{n} grid")));
            }
            // rows from the north
            let (n0, n1) = if xyz { (r0, r1) } else { (n - 1 - r1, n - 1 - r0) };
            let size = 2.0 * MERCATOR_HALF / n as f64;
            [
                -MERCATOR_HALF + c0 as f64 * size,
                MERCATOR_HALF - (n1 + 1) as f64 * size,
                -MERCATOR_HALF + (c1 + 1) as f64 * size,
                MERCATOR_HALF - n0 as f64 * size,
            ]
        }
    };
    let double = side == 2 * TILE;
    let zoom = max + double as u32;
    // bounds written at texel edges to a few decimals must not take in a
    // sliver of the texel beyond: shrunk by a quarter texel (as a store's
    // description is checked), at most a quarter of the extent, before the
    // extent is rounded out to whole texels
    let texel = 2.0 * MERCATOR_HALF / (TILE as f64 * (1u64 << zoom) as f64);
    let (ex, ey) = ((texel / 4.0).min((bounds[2] - bounds[0]) / 4.0), (texel / 4.0).min((bounds[3] - bounds[1]) / 4.0));
    let bounds = [bounds[0] + ex, bounds[1] + ey, bounds[2] - ex, bounds[3] - ey];
    let label = value("name")?
        .filter(|n| !n.trim().is_empty())
        .unwrap_or_else(|| path.file_stem().map_or_else(|| "MBTiles".into(), |s| s.to_string_lossy().into_owned()));
    let meta = StoreMeta::mercator(bounds, zoom, &format!("{label} (an MBTiles file by another tool)"))
        .map_err(|e| fmt(format!("its extent at zoom {zoom}: {e}")))?;
    // the zooms the file holds (from the index), in the store's zooms
    let mut st =
        conn.prepare("SELECT DISTINCT zoom_level FROM tiles ORDER BY zoom_level").map_err(|e| sql_err(path, e))?;
    let zooms: Vec<u32> = st
        .query_map([], |r| r.get::<_, i64>(0))
        .map_err(|e| sql_err(path, e))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| sql_err(path, e))?
        .into_iter()
        .map(|z| z as u32 + double as u32)
        .collect();
    // every run of zooms the file lacks is built from the zoom below it
    for (k, &held) in zooms.iter().enumerate() {
        let above = if k == 0 { meta.zoom(0) } else { zooms[k - 1] + 1 };
        if held > above && held > meta.zoom(0) {
            let n = meta.data_count(held - meta.zoom(0));
            if n > MAX_FOREIGN_BUILD_TILES {
                let (file_zoom, levels) = (held - double as u32, held - above.max(meta.zoom(0)));
                let which = if k == 0 {
                    format!("coarsest tiles (zoom {file_zoom})")
                } else {
                    format!("zoom-{file_zoom} tiles")
                };
                return Err(fmt(format!(
                    "its {which} number {n} over its extent; hitex builds the {levels} coarser levels its pyramid \
                     needs from at most {MAX_FOREIGN_BUILD_TILES}: add coarser zooms to the file"
                )));
            }
        }
    }
    Ok((meta, Foreign { side, xyz, zooms, built: Mutex::new(HashMap::new()) }))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gst::{BuildOptions, FolderSink, MemorySource, Store, build_into, read_tile};

    fn tmp(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::fresh(&format!("mbtiles-{name}"))
    }

    /// A web-mercator store over 600×450 texels near Olinda at zoom 14 and a
    /// source of that size (a gradient with a transparent corner).
    fn sample() -> (StoreMeta, MemorySource) {
        let (x, y) = (-3_882_000.0, -892_000.0);
        let meta = StoreMeta::mercator([x, y - 4300.0, x + 5700.0, y], 14, "sample").unwrap();
        let (w, h) = (meta.width, meta.height);
        let mut rgba = Vec::with_capacity((w * h * 4) as usize);
        for j in 0..h {
            for i in 0..w {
                let a = if i < 20 && j < 20 { 0 } else { 255 };
                rgba.extend_from_slice(&[(i % 256) as u8, (j % 256) as u8, ((i + j) % 256) as u8, a]);
            }
        }
        (meta, MemorySource { width: w, height: h, rgba, name: "sample".into() })
    }

    /// A test folder named after `name` holding `good.mbtiles`, hitex's
    /// build of [`sample`]; with the sample's description and source.
    fn built(name: &str) -> (crate::test_dir::TestDir, StoreMeta, MemorySource, PathBuf) {
        let d = tmp(name);
        let (meta, src) = sample();
        let good = d.join("good.mbtiles");
        build_mbtiles(&src, &meta, &good, &[], &|_, _| {}).unwrap();
        (d, meta, src, good)
    }

    #[test]
    fn an_mbtiles_build_holds_the_folder_builds_maps() {
        let d = tmp("build");
        let (meta, src) = sample();
        assert!(meta.levels >= 2);
        let file = d.join("s.mbtiles");
        let dem = vec![("dem.tif".to_string(), b"not really a tiff".to_vec())];
        let r = build_mbtiles(&src, &meta, &file, &dem, &|_, _| {}).unwrap();
        assert_eq!(r.written, meta.total_tiles());
        let folder = d.join("folder");
        std::fs::create_dir_all(&folder).unwrap();
        build_into(&src, &meta, &FolderSink(&folder), BuildOptions::default(), &|_, _| {}).unwrap();
        // an SQLite reader sees the tiles, rows from the south, and the metadata
        let conn = Connection::open(&file).unwrap();
        let n: i64 = conn.query_row("SELECT count(*) FROM tiles", [], |r| r.get(0)).unwrap();
        assert_eq!(n as u64, meta.total_tiles());
        let get = |k: &str| -> String {
            conn.query_row("SELECT value FROM metadata WHERE name = ?1", [k], |r| r.get(0)).unwrap()
        };
        assert_eq!(get("format"), "png");
        assert_eq!(get("name"), "s");
        assert_eq!(get("minzoom"), meta.zoom(0).to_string());
        assert_eq!(get("maxzoom"), "14");
        let b: Vec<f64> = get("bounds").split(',').map(|v| v.parse().unwrap()).collect();
        let want = meta.lon_lat_bounds().unwrap();
        for k in 0..4 {
            assert!((b[k] - want[k]).abs() < 1e-6, "{b:?} vs {want:?}");
        }
        let (minz, maxz): (i64, i64) = conn
            .query_row("SELECT min(zoom_level), max(zoom_level) FROM tiles", [], |r| Ok((r.get(0)?, r.get(1)?)))
            .unwrap();
        assert_eq!((minz, maxz), (meta.zoom(0) as i64, 14));
        drop(conn);
        // and hitex reads back the folder build's maps, bit for bit
        let store = Store::open(&file).unwrap();
        assert!(store.is_mbtiles());
        assert_eq!(store.meta, meta);
        for z in 0..meta.levels {
            for (x, y) in meta.data_maps(z) {
                assert_eq!(
                    store.read_tile(z, x, y).unwrap(),
                    read_tile(&meta, &folder, z, x, y).unwrap(),
                    "{z}/{x}/{y}"
                );
            }
        }
        let (name, bytes) = store.dem().unwrap().unwrap();
        assert!(name.ends_with("dem.tif") && bytes == dem[0].1);
        // no partial file left beside it
        let left: Vec<_> = std::fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(left.len(), 2, "{left:?}");
        // packed from the folder form: the same tiles, byte for byte
        std::fs::write(folder.join("metadata.json"), serde_json::to_string(&meta).unwrap()).unwrap();
        std::fs::write(folder.join("dem.tif"), &dem[0].1).unwrap();
        let packed = d.join("p.mbtiles");
        assert_eq!(pack_folder(&folder, &packed, &|_, _| {}).unwrap(), meta.total_tiles());
        let (a, b) = (Connection::open(&file).unwrap(), Connection::open(&packed).unwrap());
        let all = |c: &Connection| -> Vec<(i64, i64, i64, Vec<u8>)> {
            let mut st = c.prepare("SELECT * FROM tiles ORDER BY zoom_level, tile_column, tile_row").unwrap();
            st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
                .unwrap()
                .map(Result::unwrap)
                .collect()
        };
        assert_eq!(all(&a), all(&b));
    }

    #[test]
    fn broken_mbtiles_files_are_named_errors() {
        let (d, meta, src, good) = built("broken");
        let err = |p: &Path| match Store::open(p) {
            Ok(s) => s.read_tile(0, 0, 0).err().map(|e| e.to_string()).unwrap_or_else(|| "ok".into()),
            Err(e) => e.to_string(),
        };
        // not SQLite at all, and a truncated file
        let p = d.join("text.mbtiles");
        std::fs::write(&p, "hello").unwrap();
        assert!(err(&p).contains("text.mbtiles"), "{}", err(&p));
        let bytes = std::fs::read(&good).unwrap();
        let p = d.join("cut.mbtiles");
        std::fs::write(&p, &bytes[..bytes.len() / 3]).unwrap();
        let e = err(&p);
        assert!(e.contains("cut.mbtiles") && e != "ok", "{e}");
        // SQLite without the tables
        let p = d.join("empty.mbtiles");
        Connection::open(&p).unwrap().execute_batch("CREATE TABLE t (x);").unwrap();
        assert!(err(&p).contains("not an MBTiles file"), "{}", err(&p));
        // a description that lies about its levels
        let p = d.join("lie.mbtiles");
        std::fs::copy(&good, &p).unwrap();
        let mut lie = meta.clone();
        lie.levels += 1;
        Connection::open(&p)
            .unwrap()
            .execute("UPDATE metadata SET value = ?1 WHERE name = 'hitex'", [serde_json::to_string(&lie).unwrap()])
            .unwrap();
        assert!(err(&p).contains("levels"), "{}", err(&p));
        // a missing tile, an oversized one, a corrupt one
        let p = d.join("holes.mbtiles");
        std::fs::copy(&good, &p).unwrap();
        Connection::open(&p).unwrap().execute("DELETE FROM tiles WHERE zoom_level = ?1", [meta.zoom(0)]).unwrap();
        assert!(err(&p).contains("no tile"), "{}", err(&p));
        let p = d.join("big.mbtiles");
        std::fs::copy(&good, &p).unwrap();
        Connection::open(&p)
            .unwrap()
            .execute("UPDATE tiles SET tile_data = zeroblob(?1) WHERE zoom_level = ?2", params![5 << 20, meta.zoom(0)])
            .unwrap();
        assert!(err(&p).contains("bytes"), "{}", err(&p));
        let p = d.join("bad.mbtiles");
        std::fs::copy(&good, &p).unwrap();
        Connection::open(&p)
            .unwrap()
            .execute("UPDATE tiles SET tile_data = x'89504e47' WHERE zoom_level = ?1", [meta.zoom(0)])
            .unwrap();
        let e = err(&p);
        assert!(e.contains("bad.mbtiles") && e.contains(&format!("{}/", meta.zoom(0))), "{e}");
        // a destination that is not an MBTiles file is left alone
        let p = d.join("mine.mbtiles");
        std::fs::write(&p, "my notes").unwrap();
        assert!(build_mbtiles(&src, &meta, &p, &[], &|_, _| {}).is_err());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "my notes");
        // a local pyramid is no MBTiles
        let local = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
        let psrc = crate::gst::ProceduralSource { width: 300, height: 300, seed: 1 };
        assert!(build_mbtiles(&psrc, &local, &d.join("local.mbtiles"), &[], &|_, _| {}).is_err());
        assert!(!d.join("local.mbtiles").exists());
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().contains("partial"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }

    /// A copy of `good` as another tool would have made it: no hitex row, no
    /// stored files, `sql` applied on top.
    fn foreign_copy(good: &Path, to: &Path, sql: &str) {
        std::fs::copy(good, to).unwrap();
        let c = Connection::open(to).unwrap();
        c.execute_batch("DELETE FROM metadata WHERE name = 'hitex'; DROP TABLE hitex_files;").unwrap();
        c.execute_batch(sql).unwrap();
    }

    fn png(w: u32, h: u32, rgba: &[u8]) -> Vec<u8> {
        use image::ImageEncoder;
        let mut buf = Vec::new();
        image::codecs::png::PngEncoder::new(&mut buf).write_image(rgba, w, h, image::ExtendedColorType::Rgba8).unwrap();
        buf
    }

    #[test]
    fn another_tools_mbtiles_reads_as_the_same_store() {
        let (d, meta, _, good) = built("foreign");
        assert!(meta.levels >= 3, "{}", meta.levels);
        let hitex = Store::open(&good).unwrap();
        // only the finest zoom kept: every coarser level is built on reading
        let p = d.join("only14.mbtiles");
        foreign_copy(&good, &p, "DELETE FROM tiles WHERE zoom_level < 14;");
        let other = Store::open(&p).unwrap();
        assert_eq!(other.meta.levels, meta.levels);
        assert_eq!((other.meta.width, other.meta.height, other.meta.offset), (meta.width, meta.height, meta.offset));
        assert_eq!((other.meta.origin, other.meta.tiles), (meta.origin, meta.tiles));
        assert!(other.meta.source.contains("another tool"), "{}", other.meta.source);
        assert!(other.dem().unwrap().is_none());
        // the same filter over the same children: the same bits, twice (kept maps)
        for _ in 0..2 {
            for z in 0..meta.levels {
                for (x, y) in meta.data_maps(z) {
                    assert!(other.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
                }
            }
        }
        // a zoom between two the file holds is built from the one below it
        let p = d.join("gap.mbtiles");
        foreign_copy(&good, &p, "DELETE FROM tiles WHERE zoom_level = 13;");
        let gap = Store::open(&p).unwrap();
        for z in 0..meta.levels {
            for (x, y) in meta.data_maps(z) {
                assert!(gap.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
            }
        }
        // without a bounds row the extent is the deepest tiles' squares
        let p = d.join("nobounds.mbtiles");
        foreign_copy(&good, &p, "DELETE FROM metadata WHERE name = 'bounds';");
        let nb = Store::open(&p).unwrap();
        let deepest = meta.data_range(meta.levels - 1);
        assert_eq!(nb.meta.offset, [deepest[0] * TILE, deepest[1] * TILE]);
        assert_eq!(nb.meta.width, (deepest[2] - deepest[0]) * TILE);
        assert_eq!(nb.meta.tiles, meta.tiles);
        // a JPEG tile reads within JPEG's error; a tile the file omits is transparent
        let (x, y) = meta.data_maps(meta.levels - 1).nth(1).unwrap();
        let (col, row) = (meta.global_tile(meta.levels - 1, x, y).0, meta.tms_row(meta.levels - 1, y));
        let want = hitex.read_tile(meta.levels - 1, x, y).unwrap();
        let rgb: Vec<u8> = want.chunks_exact(4).flat_map(|c| [c[0], c[1], c[2]]).collect();
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 95)
            .encode(&rgb, TILE, TILE, image::ExtendedColorType::Rgb8)
            .unwrap();
        let p = d.join("jpeg.mbtiles");
        foreign_copy(&good, &p, "UPDATE metadata SET value = 'jpg' WHERE name = 'format';");
        Connection::open(&p)
            .unwrap()
            .execute(
                "UPDATE tiles SET tile_data = ?1 WHERE zoom_level = 14 AND tile_column = ?2 AND tile_row = ?3",
                params![jpg, col, row],
            )
            .unwrap();
        let got = Store::open(&p).unwrap().read_tile(meta.levels - 1, x, y).unwrap();
        // over the texels inside the data (JPEG has no alpha: opaque everywhere)
        let (mut sum, mut n) = (0.0, 0);
        for (g, w) in got.chunks_exact(4).zip(want.chunks_exact(4)) {
            assert_eq!(g[3], 255);
            if w[3] == 255 {
                sum += (0..3).map(|k| (g[k] as f64 - w[k] as f64).abs()).sum::<f64>();
                n += 3;
            }
        }
        assert!(n > 30_000 && sum / n as f64 <= 3.0 && got != want, "mean |Δ| {} over {n}", sum / n as f64);
        let p = d.join("hole.mbtiles");
        foreign_copy(
            &good,
            &p,
            &format!("DELETE FROM tiles WHERE zoom_level = 14 AND tile_column = {col} AND tile_row = {row};"),
        );
        assert!(Store::open(&p).unwrap().read_tile(meta.levels - 1, x, y).unwrap().iter().all(|&b| b == 0));
    }

    /// Bounds at tile edges written to 7 decimals (as tools write them) lie up
    /// to 6 mm outside the tiles: at zoom 17 (1.2 m texels) the extent takes
    /// in no texel, and so no level, beyond them.
    #[test]
    fn bounds_at_tile_edges_to_seven_decimals_take_in_no_extra_texel() {
        let (d, _, _, good) = built("foreign-edges");
        // one zoom-12 tile's square (column 1625, row 2063 from the north), its zoom-17 tiles
        let p = d.join("z17.mbtiles");
        foreign_copy(
            &good,
            &p,
            "UPDATE metadata SET value = '-37.1777344,-1.4061088,-37.0898438,-1.3182431' WHERE name = 'bounds';
             DELETE FROM tiles WHERE zoom_level < 14; UPDATE tiles SET zoom_level = 17;",
        );
        let m = Store::open(&p).unwrap().meta;
        assert_eq!((m.width, m.height, m.offset), (8192, 8192, [0, 0]));
        assert_eq!((m.levels, m.tiles), (6, [12, 1625, 2063]));
    }

    #[test]
    fn tiles_of_512_texels_are_four_maps_each() {
        let (d, meta, _, good) = built("foreign512");
        let hitex = Store::open(&good).unwrap();
        // zoom-13 tiles of 512 texels stitched from the zoom-14 maps, rows from the north
        let fine = meta.levels - 1;
        let [x0, y0, x1, y1] = meta.data_range(fine);
        let p = d.join("big.mbtiles");
        foreign_copy(&good, &p, "DELETE FROM tiles; INSERT INTO metadata VALUES ('scheme', 'xyz');");
        let conn = Connection::open(&p).unwrap();
        let mut done = std::collections::HashSet::new();
        for y in y0..y1 {
            for x in x0..x1 {
                let (gx, gy) = meta.global_tile(fine, x, y);
                if !done.insert((gx / 2, gy / 2)) {
                    continue;
                }
                let mut big = vec![0u8; (4 * TILE * TILE * 4) as usize];
                for (dx, dy) in [(0u32, 0u32), (1, 0), (0, 1), (1, 1)] {
                    let (cx, cy) = ((gx / 2 * 2 + dx) - (gx - x), (gy / 2 * 2 + dy) - (gy - y));
                    if cx < x0 || cy < y0 || cx >= x1 || cy >= y1 {
                        continue;
                    }
                    let m = hitex.read_tile(fine, cx, cy).unwrap();
                    for j in 0..TILE {
                        let o = (((dy * TILE + j) * 2 * TILE + dx * TILE) * 4) as usize;
                        let i = (j * TILE * 4) as usize;
                        big[o..o + (TILE * 4) as usize].copy_from_slice(&m[i..i + (TILE * 4) as usize]);
                    }
                }
                conn.execute(
                    "INSERT INTO tiles VALUES (13, ?1, ?2, ?3)",
                    params![gx / 2, gy / 2, png(2 * TILE, 2 * TILE, &big)],
                )
                .unwrap();
            }
        }
        drop(conn);
        let other = Store::open(&p).unwrap();
        assert_eq!((other.meta.tiles, other.meta.levels, other.meta.offset), (meta.tiles, meta.levels, meta.offset));
        for z in 0..meta.levels {
            for (x, y) in meta.data_maps(z) {
                assert!(other.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
            }
        }
    }

    #[test]
    fn foreign_mbtiles_hitex_cannot_fly_are_named_errors() {
        let (d, meta, _, good) = built("foreign-bad");
        let err = |name: &str, sql: &str| -> String {
            let p = d.join(name);
            foreign_copy(&good, &p, sql);
            let e = match Store::open(&p) {
                Ok(s) => s
                    .read_tile(
                        meta.levels - 1,
                        meta.data_range(meta.levels - 1)[0],
                        meta.data_range(meta.levels - 1)[1],
                    )
                    .err()
                    .map(|e| e.to_string())
                    .unwrap_or_else(|| "ok".into()),
                Err(e) => e.to_string(),
            };
            assert!(e.contains(name), "{name}: {e}");
            e
        };
        assert!(err("webp.mbtiles", "UPDATE metadata SET value = 'webp' WHERE name = 'format';").contains("\"webp\""));
        assert!(
            err("pbf.mbtiles", "UPDATE metadata SET value = 'pbf' WHERE name = 'format';").contains("vector tiles")
        );
        assert!(err("scheme.mbtiles", "INSERT INTO metadata VALUES ('scheme', 'quadkey');").contains("quadkey"));
        assert!(err("empty.mbtiles", "DELETE FROM tiles;").contains("no tiles"));
        assert!(err("zoom.mbtiles", "UPDATE tiles SET zoom_level = 30 WHERE zoom_level = 14;").contains("zooms"));
        assert!(
            err("bounds.mbtiles", "UPDATE metadata SET value = '-35,-8' WHERE name = 'bounds';").contains("bounds")
        );
        assert!(
            err("flip.mbtiles", "UPDATE metadata SET value = '-34,-8,-35,-7' WHERE name = 'bounds';")
                .contains("bounds")
        );
        let odd = png(300, 300, &vec![9u8; 300 * 300 * 4]);
        let p = d.join("odd.mbtiles");
        foreign_copy(&good, &p, "");
        Connection::open(&p)
            .unwrap()
            .execute("UPDATE tiles SET tile_data = ?1 WHERE zoom_level = 14", params![odd])
            .unwrap();
        let e = Store::open(&p).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("300x300") && e.contains("odd.mbtiles"), "{e}");
        // a wide extent over only its deepest tiles: too many to build level 0 from
        let e = err(
            "wide.mbtiles",
            "UPDATE metadata SET value = '-40,-12,-30,-2' WHERE name = 'bounds'; DELETE FROM tiles WHERE zoom_level < 14;",
        );
        assert!(e.contains("coarser zooms"), "{e}");
        // a corrupt tile names its zoom, column and row
        let e = err("corrupt.mbtiles", "UPDATE tiles SET tile_data = x'89504e47' WHERE zoom_level = 14;");
        assert!(e.contains("corrupt.mbtiles/14/") && e.contains("image"), "{e}");
    }
}
