//! MBTiles files made by other tools: their metadata, tile side and row
//! scheme read into a store description, and the maps they lack built from
//! their children.

use super::*;

/// Most maps of a zoom a foreign file holds within its extent from which
/// hitex builds the coarser zooms above it that the file lacks (each built
/// map reads 4^d of them, d levels down; 4,096 keeps the level-0 map to a
/// few seconds of decoding).
pub const MAX_FOREIGN_BUILD_TILES: u64 = 4096;

/// Most built maps kept once built (64 MiB); maps past it are built again
/// when asked for (the resident-map cache keeps what a flight uses).
pub(super) const MAX_KEPT_MAPS: usize = 256;

/// How the tiles of an MBTiles file made by another tool become the
/// store's maps (see the module documentation).
#[derive(Debug)]
pub(super) struct Foreign {
    /// The file's tile side: 256, or 512 (file zoom z is store zoom z + 1).
    pub(super) side: u32,
    /// Rows counted from the north (`scheme` = `xyz`), not from the south.
    pub(super) xyz: bool,
    /// The store zooms the file holds tiles of, ascending: maps of the
    /// others are built from their children.
    pub(super) zooms: Vec<u32>,
    /// Built maps two or more levels above the file's tiles (each summing
    /// 16 or more of them), kept once built.
    pub(super) built: Mutex<BuiltMaps>,
}

/// Maps built from their children, by level, column and row.
pub(super) type BuiltMaps = HashMap<(u32, u32, u32), Vec<u8>>;

pub(super) fn metadata_value(conn: &Connection, path: &Path, key: &str) -> Result<Option<String>, IoError> {
    conn.query_row("SELECT value FROM metadata WHERE name = ?1", params![key], |r| r.get::<_, Option<String>>(0))
        .optional()
        .map(Option::flatten)
        .map_err(|e| sql_err(path, e))
}

/// Web-mercator metres of a longitude and latitude in degrees (latitudes
/// past the projection's ±85.05° clamped to it).
pub(super) fn mercator_metres(lon: f64, lat: f64) -> (f64, f64) {
    let lim = (MERCATOR_HALF / MERCATOR_RADIUS).sinh().atan();
    let phi = lat.to_radians().clamp(-lim, lim);
    (MERCATOR_RADIUS * lon.to_radians(), MERCATOR_RADIUS * (std::f64::consts::FRAC_PI_4 + phi / 2.0).tan().ln())
}

/// The store an MBTiles file made by another tool describes (see the
/// module documentation), and how its tiles become maps.
pub(super) fn foreign_meta(conn: &Connection, path: &Path) -> Result<(StoreMeta, Foreign), IoError> {
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
