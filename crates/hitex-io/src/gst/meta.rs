//! What a store says about itself: `metadata.json` ([`StoreMeta`]), its
//! profile and levels, and the TMS `tilemapresource.xml` GIS tools read.

use super::*;

/// What `metadata.json` says about a store.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoreMeta {
    /// Always "hitex-gst".
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// Map side in texels.
    pub tile_size: u32,
    /// Source width in texels (finest level).
    pub width: u32,
    /// Source height in texels.
    pub height: u32,
    /// Number of levels; level `levels − 1` is the source's resolution.
    pub levels: u32,
    /// World coordinates of the source's north-west corner.
    pub origin: [f64; 2],
    /// World units per texel at the finest level (x, y).
    pub pixel: [f64; 2],
    /// Coordinate reference system, e.g. "EPSG:31985" (empty: unknown).
    pub crs: String,
    /// Where the imagery came from.
    pub source: String,
    /// Finest-level texels from the grid's north-west corner (`origin`) to
    /// the data's (0, 0 for a pyramid anchored at its data).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub offset: [u32; 2],
    /// The tiling the maps belong to: a local pyramid, or the global
    /// web-mercator one (EPSG:3857, the tiles web maps load).
    #[serde(default, skip_serializing_if = "Profile::is_local")]
    pub profile: Profile,
    /// The level-0 map's place in the global tiling: zoom, column, row from
    /// the north (0, 0, 0 for a local pyramid).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub tiles: [u32; 3],
}

pub(super) fn is_zero<const N: usize>(v: &[u32; N]) -> bool {
    v.iter().all(|&x| x == 0)
}

/// How a store's maps are tiled.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Level 0 is one map over the source, in the source's CRS.
    #[default]
    Local,
    /// The global web-mercator tiles (EPSG:3857, OSGeo TMS
    /// `global-mercator`): level z is zoom `tiles[0] + z`.
    Mercator,
}

impl Profile {
    fn is_local(&self) -> bool {
        *self == Profile::Local
    }
}

/// Half the web-mercator world's side, metres (π × 6,378,137).
pub const MERCATOR_HALF: f64 = std::f64::consts::PI * MERCATOR_RADIUS;
/// The web-mercator sphere's radius, metres.
pub const MERCATOR_RADIUS: f64 = 6_378_137.0;
/// Deepest web-mercator zoom a store is built at (about 2 cm a texel).
pub const MAX_MERCATOR_ZOOM: u32 = 23;

/// Levels of a pyramid whose finest level spans `w`×`h` texels.
pub(super) fn levels_for(w: u64, h: u64) -> u32 {
    let maps = w.div_ceil(TILE as u64).max(h.div_ceil(TILE as u64)).max(1);
    1 + maps.next_power_of_two().trailing_zeros()
}

impl StoreMeta {
    /// The metadata of a pyramid over a `width`×`height` source.
    pub fn for_source(width: u32, height: u32, origin: [f64; 2], pixel: [f64; 2], crs: &str, source: &str) -> Self {
        let levels = levels_for(width as u64, height as u64);
        Self {
            format: "hitex-gst".into(),
            version: 1,
            tile_size: TILE,
            width,
            height,
            levels,
            origin,
            pixel,
            crs: crs.into(),
            source: source.into(),
            offset: [0, 0],
            profile: Profile::Local,
            tiles: [0, 0, 0],
        }
    }

    /// The metadata of a web-mercator pyramid at `zoom` over the EPSG:3857
    /// extent `bounds` (x min, y min, x max, y max, metres): level 0 is the
    /// deepest-zoom tile holding the whole extent, the finest level is `zoom`.
    pub fn mercator(bounds: [f64; 4], zoom: u32, source: &str) -> Result<Self, crate::DataError> {
        Self::mercator_meta(bounds, zoom, source).map_err(crate::DataError::from)
    }

    fn mercator_meta(bounds: [f64; 4], zoom: u32, source: &str) -> Result<Self, String> {
        if zoom > MAX_MERCATOR_ZOOM {
            return Err(format!("zoom {zoom} is beyond {MAX_MERCATOR_ZOOM}"));
        }
        let [x0, y0, x1, y1] = bounds;
        if !bounds.iter().all(|v| v.is_finite()) || x1 <= x0 || y1 <= y0 {
            return Err(format!("no web-mercator extent ({x0}, {y0}) to ({x1}, {y1})"));
        }
        let side = TILE as u64 * (1u64 << zoom);
        let pixel = 2.0 * MERCATOR_HALF / side as f64;
        let clamp = |v: f64| v.clamp(0.0, side as f64);
        let (c0, c1) = (clamp(((x0 + MERCATOR_HALF) / pixel).floor()), clamp(((x1 + MERCATOR_HALF) / pixel).ceil()));
        let (r0, r1) = (clamp(((MERCATOR_HALF - y1) / pixel).floor()), clamp(((MERCATOR_HALF - y0) / pixel).ceil()));
        let (c0, c1, r0, r1) = (c0 as u64, (c1 as u64).max(c0 as u64 + 1), r0 as u64, (r1 as u64).max(r0 as u64 + 1));
        let (w, h) = (c1 - c0, r1 - r0);
        if w > MAX_SOURCE_SIDE as u64 || h > MAX_SOURCE_SIDE as u64 {
            return Err(format!("{w}x{h} texels at zoom {zoom}, beyond {MAX_SOURCE_SIDE} a side"));
        }
        // the smallest k whose zoom − k tile holds the extent
        let k = (0..=zoom)
            .find(|&k| {
                let span = TILE as u64 * (1u64 << k);
                c0 / span == (c1 - 1) / span && r0 / span == (r1 - 1) / span
            })
            .unwrap_or(zoom);
        let span = TILE as u64 * (1u64 << k);
        if span > MAX_SOURCE_SIDE as u64 {
            return Err(format!(
                "the extent straddles the edge of zoom-{} tiles: its pyramid would be {span} texels across at zoom {zoom}, \
                 beyond {MAX_SOURCE_SIDE}; build it with the local profile",
                zoom - k
            ));
        }
        let (tx, ty) = (c0 / span, r0 / span);
        let origin = [-MERCATOR_HALF + (tx * span) as f64 * pixel, MERCATOR_HALF - (ty * span) as f64 * pixel];
        Ok(Self {
            format: "hitex-gst".into(),
            version: 1,
            tile_size: TILE,
            width: w as u32,
            height: h as u32,
            levels: k + 1,
            origin,
            pixel: [pixel, pixel],
            crs: "EPSG:3857".into(),
            source: source.into(),
            offset: [(c0 - tx * span) as u32, (r0 - ty * span) as u32],
            profile: Profile::Mercator,
            tiles: [zoom - k, tx as u32, ty as u32],
        })
    }

    /// World coordinates of the data's north-west corner.
    pub fn data_origin(&self) -> [f64; 2] {
        [self.origin[0] + self.offset[0] as f64 * self.pixel[0], self.origin[1] - self.offset[1] as f64 * self.pixel[1]]
    }

    /// Metres on the ground per finest texel along x: the pixel size, or
    /// for web mercator the pixel size times the cosine of the data's
    /// central latitude (the projection's scale there).
    pub fn ground_pixel(&self) -> f64 {
        match self.profile {
            Profile::Local => self.pixel[0],
            Profile::Mercator => {
                let y = self.data_origin()[1] - self.height as f64 / 2.0 * self.pixel[1];
                self.pixel[0] * (y / MERCATOR_RADIUS).sinh().atan().cos()
            }
        }
    }

    /// The data's extent in longitude and latitude (west, south, east,
    /// north, degrees) for a web-mercator store.
    pub fn lon_lat_bounds(&self) -> Option<[f64; 4]> {
        if self.profile != Profile::Mercator {
            return None;
        }
        let [x0, y1] = self.data_origin();
        let (x1, y0) = (x0 + self.width as f64 * self.pixel[0], y1 - self.height as f64 * self.pixel[1]);
        let lon = |x: f64| (x / MERCATOR_RADIUS).to_degrees();
        let lat = |y: f64| (y / MERCATOR_RADIUS).sinh().atan().to_degrees();
        Some([lon(x0), lat(y0), lon(x1), lat(y1)])
    }

    /// The global zoom of level `z` (equal to `z` for a local pyramid).
    pub fn zoom(&self, z: u32) -> u32 {
        self.tiles[0] + z
    }

    /// The global column and row (from the north) of map (x, y) of level `z`.
    pub fn global_tile(&self, z: u32, x: u32, y: u32) -> (u32, u32) {
        ((self.tiles[1] << z) + x, (self.tiles[2] << z) + y)
    }

    /// Finest-level texels per texel of level `z`.
    pub fn scale(&self, z: u32) -> u64 {
        1u64 << (self.levels - 1 - z.min(self.levels - 1))
    }

    /// Maps holding data at level `z`: first column, first row (from the
    /// north), and one past the last of each.
    pub fn data_range(&self, z: u32) -> [u32; 4] {
        let span = TILE as u64 * self.scale(z);
        let (ox, oy) = (self.offset[0] as u64, self.offset[1] as u64);
        [
            (ox / span) as u32,
            (oy / span) as u32,
            (ox + self.width as u64).div_ceil(span) as u32,
            (oy + self.height as u64).div_ceil(span) as u32,
        ]
    }

    /// The maps of level `z` holding data, row by row.
    pub fn data_maps(&self, z: u32) -> impl Iterator<Item = (u32, u32)> {
        let [x0, y0, x1, y1] = self.data_range(z);
        (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
    }

    /// How many maps of level `z` hold data.
    pub fn data_count(&self, z: u32) -> u64 {
        let [x0, y0, x1, y1] = self.data_range(z);
        (x1 - x0) as u64 * (y1 - y0) as u64
    }

    /// The TMS row (counted from the south) of map row `y` (from the north) of level `z`.
    pub fn tms_row(&self, z: u32, y: u32) -> u32 {
        let (_, gy) = self.global_tile(z, 0, y);
        ((1u64 << self.zoom(z)) - 1 - gy as u64) as u32
    }

    /// The TMS file of map (x, y-from-north) at level `z`:
    /// `zoom/column/row_from_south.png`.
    pub fn tile_path(&self, root: &Path, z: u32, x: u32, y: u32) -> PathBuf {
        let (gx, _) = self.global_tile(z, x, y);
        root.join(self.zoom(z).to_string()).join(gx.to_string()).join(format!("{}.png", self.tms_row(z, y)))
    }

    /// Maps of all levels.
    pub fn total_tiles(&self) -> u64 {
        (0..self.levels).map(|z| self.data_count(z)).sum()
    }

    /// `tilemapresource.xml` (OSGeo TMS 1.0.0): a local pyramid anchored at
    /// its grid's north-west corner and padded to 2^z maps per side, or the
    /// `global-mercator` profile.
    pub fn tms_xml(&self) -> String {
        let ([minx, maxy], [w, h]) = match self.profile {
            // the padded grid
            Profile::Local => (self.origin, [TILE as f64 * (1u64 << (self.levels - 1)) as f64; 2]),
            // the data
            Profile::Mercator => (self.data_origin(), [self.width as f64, self.height as f64]),
        };
        let (maxx, miny) = (minx + w * self.pixel[0], maxy - h * self.pixel[1]);
        let (profile, ox, oy) = match self.profile {
            Profile::Local => ("none", minx, miny),
            Profile::Mercator => ("global-mercator", -MERCATOR_HALF, -MERCATOR_HALF),
        };
        let mut s = String::from("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
        s += "<TileMap version=\"1.0.0\" tilemapservice=\"http://tms.osgeo.org/1.0.0\">\n";
        s += "  <Title>hitex geospecific texture pyramid</Title>\n";
        s += &format!("  <Abstract>{}</Abstract>\n", xml_escape(&self.source));
        s += &format!("  <SRS>{}</SRS>\n", xml_escape(&self.crs));
        s += &format!("  <BoundingBox minx=\"{minx}\" miny=\"{miny}\" maxx=\"{maxx}\" maxy=\"{maxy}\"/>\n");
        s += &format!("  <Origin x=\"{ox}\" y=\"{oy}\"/>\n");
        s += &format!("  <TileFormat width=\"{TILE}\" height=\"{TILE}\" mime-type=\"image/png\" extension=\"png\"/>\n");
        s += &format!("  <TileSets profile=\"{profile}\">\n");
        for z in 0..self.levels {
            let upp = self.pixel[0] * self.scale(z) as f64;
            let zoom = self.zoom(z);
            s += &format!("    <TileSet href=\"{zoom}\" units-per-pixel=\"{upp}\" order=\"{zoom}\"/>\n");
        }
        s += "  </TileSets>\n</TileMap>\n";
        s
    }
}

pub(super) fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Parses and checks a store's `metadata.json` held in memory; `path` is the
/// file named in errors.
pub fn parse_store_meta(text: &str, path: &Path) -> Result<StoreMeta, IoError> {
    let path = path.to_path_buf();
    let meta: StoreMeta =
        serde_json::from_str(text).map_err(|e| IoError::Format { path: path.clone(), message: e.to_string() })?;
    let bad = |m: String| Err(IoError::Format { path: path.clone(), message: m });
    if meta.format != "hitex-gst" || meta.version != 1 {
        return bad(format!("format '{}' version {}: not a hitex GST store (version 1)", meta.format, meta.version));
    }
    if meta.tile_size != TILE {
        return bad(format!("maps of {} texels; hitex builds {TILE}", meta.tile_size));
    }
    if meta.width == 0 || meta.height == 0 || meta.width > MAX_SOURCE_SIDE || meta.height > MAX_SOURCE_SIDE {
        return bad(format!("source of {}x{} texels", meta.width, meta.height));
    }
    let want = levels_for(meta.offset[0] as u64 + meta.width as u64, meta.offset[1] as u64 + meta.height as u64);
    if meta.levels != want {
        return bad(format!(
            "{} levels; a {}x{} source {}has {want}",
            meta.levels,
            meta.width,
            meta.height,
            if meta.offset == [0, 0] {
                String::new()
            } else {
                format!("{:?} texels from the grid's corner ", meta.offset)
            }
        ));
    }
    match meta.profile {
        Profile::Local if meta.tiles != [0, 0, 0] => {
            return bad(format!("a local pyramid placed at global tile {:?}", meta.tiles));
        }
        Profile::Mercator => {
            let [zoom, x, y] = meta.tiles;
            let finest = zoom as u64 + meta.levels as u64 - 1;
            if finest > MAX_MERCATOR_ZOOM as u64 || x as u64 >= 1u64 << zoom || y as u64 >= 1u64 << zoom {
                return bad(format!("web-mercator tile {:?} with {} levels", meta.tiles, meta.levels));
            }
            let again = StoreMeta::mercator(
                {
                    let [x0, y1] = meta.data_origin();
                    let (x1, y0) = (x0 + meta.width as f64 * meta.pixel[0], y1 - meta.height as f64 * meta.pixel[1]);
                    let inset = meta.pixel[0] / 4.0;
                    [x0 + inset, y0 + inset, x1 - inset, y1 - inset]
                },
                finest as u32,
                &meta.source,
            );
            match again {
                Ok(m)
                    if (m.offset, m.tiles, m.width, m.height) == (meta.offset, meta.tiles, meta.width, meta.height)
                        && (m.pixel[0] - meta.pixel[0]).abs() <= 1e-9 * m.pixel[0]
                        && m.origin.iter().zip(&meta.origin).all(|(a, b)| (a - b).abs() <= 1e-3 * m.pixel[0])
                        && meta.crs == "EPSG:3857" => {}
                _ => {
                    return bad(format!(
                        "web-mercator tile {:?}, offset {:?}, pixel {:?}, CRS '{}' do not describe one zoom-{finest} extent",
                        meta.tiles, meta.offset, meta.pixel, meta.crs
                    ));
                }
            }
        }
        Profile::Local => {}
    }
    if !meta.origin.iter().chain(meta.pixel.iter()).all(|v| v.is_finite()) || meta.pixel.iter().any(|&p| p <= 0.0) {
        return bad("origin and pixel size must be finite, pixel sizes positive".into());
    }
    Ok(meta)
}
