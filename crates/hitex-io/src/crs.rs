//! Coordinate reference systems: EPSG codes resolved to their PROJ.4
//! definitions (`crs-definitions`, EPSG's register as distributed) and
//! transformed by `proj4rs` (a pure-Rust port of PROJ.4's projections and
//! datum shifts). Geographic coordinates are degrees (longitude, latitude)
//! at this interface; projected ones are the CRS's own units.

use crate::geotiff::GeoRaster;

/// Why a coordinate reference system cannot be made or used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CrsError {
    /// The EPSG code is not in the register.
    #[error("EPSG:{0} is not in the coordinate library's register")]
    UnknownEpsg(u32),
    /// The EPSG code's definition is refused by the coordinate library.
    #[error("EPSG:{code} ({definition}) cannot be used: {reason}")]
    UnusableEpsg {
        /// The code.
        code: u16,
        /// Its PROJ.4 definition.
        definition: String,
        /// Why it was refused.
        reason: Box<CrsError>,
    },
    /// The coordinate library cannot read a PROJ.4 definition.
    #[error("{0}")]
    Definition(String),
    /// The projection cannot be inverted.
    #[error("{0}: the projection has no inverse")]
    NoInverse(String),
    /// `EPSG:` followed by something that is not a code.
    #[error("'{0}': the EPSG code is not a number")]
    BadEpsgCode(String),
    /// A name that is neither `EPSG:N` nor a definition.
    #[error("'{0}' is neither EPSG:N nor a PROJ.4 definition (+proj=…)")]
    NotACrs(String),
    /// A local frame asked for at a place that has none.
    #[error("no local frame at longitude {lon}°, latitude {lat}°")]
    NoLocalFrame {
        /// Longitude, degrees.
        lon: f64,
        /// Latitude, degrees.
        lat: f64,
    },
    /// A raster's GeoKeys name no system the library resolves.
    #[error("no coordinate reference system the coordinate library can resolve ({0}): the GeoKeys name no EPSG code")]
    Unresolved(String),
}

/// A coordinate reference system that points can be transformed between.
#[derive(Clone)]
pub struct Crs {
    proj: proj4rs::Proj,
    name: String,
    definition: String,
}

impl std::fmt::Debug for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Crs({}: {})", self.name, self.definition)
    }
}

impl PartialEq for Crs {
    fn eq(&self, other: &Self) -> bool {
        self.definition == other.definition
    }
}

impl Crs {
    /// The CRS of EPSG code `code`.
    pub fn from_epsg(code: u16) -> Result<Crs, CrsError> {
        let def = crs_definitions::from_code(code).ok_or(CrsError::UnknownEpsg(code as u32))?;
        Self::from_definition(def.proj4, &format!("EPSG:{code}")).map_err(|e| CrsError::UnusableEpsg {
            code,
            definition: def.proj4.to_string(),
            reason: Box::new(e),
        })
    }

    /// The CRS of a PROJ.4 definition (`+proj=… +datum=…`), named `name` in messages.
    pub fn from_definition(definition: &str, name: &str) -> Result<Crs, CrsError> {
        let proj = proj4rs::Proj::from_proj_string(definition).map_err(|e| CrsError::Definition(e.to_string()))?;
        if !(proj.has_forward() && proj.has_inverse()) {
            return Err(CrsError::NoInverse(name.to_string()));
        }
        Ok(Crs { proj, name: name.to_string(), definition: definition.to_string() })
    }

    /// A CRS named by the user: `EPSG:N` or a PROJ.4 definition.
    pub fn parse(s: &str) -> Result<Crs, CrsError> {
        let s = s.trim();
        if let Some(code) = s.strip_prefix("EPSG:").or_else(|| s.strip_prefix("epsg:")) {
            let code: u32 = code.trim().parse().map_err(|_| CrsError::BadEpsgCode(s.to_string()))?;
            // codes run to 32767 (EPSG's own) and a little beyond (ESRI's)
            let code = u16::try_from(code).map_err(|_| CrsError::UnknownEpsg(code))?;
            return Self::from_epsg(code);
        }
        if s.starts_with('+') {
            return Self::from_definition(s, s);
        }
        Err(CrsError::NotACrs(s.to_string()))
    }

    /// The local metric frame of an area centred at (`lon`, `lat`) degrees:
    /// a transverse Mercator on WGS 84 through the centre with scale 1 there
    /// (x east, y north, metres). Within 50 km of the centre its scale
    /// departs from 1 by less than 4·10⁻⁵ and its axes from east and north
    /// by less than the meridian convergence of the centre's neighbourhood.
    pub fn local(lon: f64, lat: f64) -> Result<Crs, CrsError> {
        if !(lon.is_finite() && lat.is_finite() && lat.abs() < 90.0) {
            return Err(CrsError::NoLocalFrame { lon, lat });
        }
        // rounded as the definition states them, so that a frame read back from GeoKeys is equal
        let (lon, lat) = ((lon * 1e9).round() / 1e9, (lat * 1e9).round() / 1e9);
        Self::from_definition(&tm_definition(lon, lat, 1.0, 0.0, 0.0), &local_name(lon, lat))
    }

    /// The parameters (central meridian, latitude of origin, scale, false
    /// easting, false northing) of a transverse Mercator on WGS 84 in metres
    /// made by [`Crs::local`] or read from user-defined GeoKeys.
    pub fn transverse_mercator(&self) -> Option<[f64; 5]> {
        let rest = self.definition.strip_prefix("+proj=tmerc ")?;
        let mut v = [f64::NAN, f64::NAN, 1.0, 0.0, 0.0];
        for part in rest.split_whitespace() {
            let (k, val) = match part.split_once('=') {
                Some(kv) => kv,
                None => continue,
            };
            let slot = match k {
                "+lon_0" => 0,
                "+lat_0" => 1,
                "+k" => 2,
                "+x_0" => 3,
                "+y_0" => 4,
                "+datum" if val == "WGS84" => continue,
                "+units" if val == "m" => continue,
                _ => return None,
            };
            v[slot] = val.parse().ok()?;
        }
        v.iter().all(|x| x.is_finite()).then_some(v)
    }

    /// WGS 84 longitude, latitude (degrees).
    pub fn wgs84() -> Crs {
        Self::from_definition("+proj=longlat +datum=WGS84 +no_defs", "WGS 84 (EPSG:4326)")
            .unwrap_or_else(|_| unreachable!("WGS 84 always parses"))
    }

    /// The EPSG code the CRS was made from, if any.
    pub fn epsg(&self) -> Option<u16> {
        self.name.strip_prefix("EPSG:").and_then(|c| c.parse().ok())
    }

    /// Name in messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The PROJ.4 definition.
    pub fn definition(&self) -> &str {
        &self.definition
    }

    /// Whether coordinates are longitude and latitude (degrees).
    pub fn is_geographic(&self) -> bool {
        self.proj.is_latlong()
    }

    /// Metres per unit of a projected CRS (1 for metres, 0.3048 for feet).
    pub fn unit_metres(&self) -> f64 {
        if self.is_geographic() { 1.0 } else { self.proj.to_meter() }
    }

    /// Transforms points (x, y) of this CRS into `to` in place; a point the
    /// projection cannot take (outside its domain) becomes NaN.
    pub fn transform(&self, to: &Crs, points: &mut [[f64; 2]]) {
        let (src_deg, dst_deg) = (self.is_geographic(), to.is_geographic());
        for p in points.iter_mut() {
            let mut q = if src_deg { (p[0].to_radians(), p[1].to_radians(), 0.0) } else { (p[0], p[1], 0.0) };
            let ok = p[0].is_finite()
                && p[1].is_finite()
                && proj4rs::transform::transform(&self.proj, &to.proj, &mut q).is_ok()
                && q.0.is_finite()
                && q.1.is_finite();
            *p = match (ok, dst_deg) {
                (false, _) => [f64::NAN; 2],
                (true, true) => [q.0.to_degrees(), q.1.to_degrees()],
                (true, false) => [q.0, q.1],
            };
        }
    }

    /// One point (x, y) of this CRS in `to`; NaN outside the projection's domain.
    pub fn point(&self, to: &Crs, p: [f64; 2]) -> [f64; 2] {
        let mut v = [p];
        self.transform(to, &mut v);
        v[0]
    }
}

/// The PROJ.4 definition of a transverse Mercator on WGS 84 in metres.
pub(crate) fn tm_definition(lon: f64, lat: f64, k: f64, fe: f64, fn_: f64) -> String {
    format!("+proj=tmerc +lat_0={lat:.9} +lon_0={lon:.9} +k={k} +x_0={fe} +y_0={fn_} +datum=WGS84 +units=m")
}

fn local_name(lon: f64, lat: f64) -> String {
    format!("a local metric frame at {lat:.4}°, {lon:.4}°")
}

impl GeoRaster {
    /// The raster's CRS through the coordinate library: its EPSG code, or
    /// the UTM zone a user-defined projection code names.
    pub fn crs(&self) -> Result<Crs, CrsError> {
        if let Some(def) = &self.proj4 {
            let crs = Crs::from_definition(def, self.citation.as_deref().unwrap_or(def))?;
            // a local frame keeps its name
            return Ok(match crs.transverse_mercator() {
                Some([lon, lat, k, fe, fn_]) if k == 1.0 && fe == 0.0 && fn_ == 0.0 => {
                    Crs { name: local_name(lon, lat), ..crs }
                }
                _ => crs,
            });
        }
        match (self.epsg, self.utm_zone()) {
            (Some(c), _) if c != 32767 => Crs::from_epsg(c),
            (_, Some(z)) => Crs::from_definition(
                &format!(
                    "+proj=utm +zone={}{} +datum=WGS84 +units=m +no_defs",
                    z.abs(),
                    if z < 0 { " +south" } else { "" }
                ),
                &self.crs_name(),
            ),
            _ => Err(CrsError::Unresolved(self.citation.as_deref().unwrap_or("no citation").to_string())),
        }
    }

    /// Whether the raster's coordinates are longitude and latitude.
    pub fn is_geographic(&self) -> bool {
        self.crs().is_ok_and(|c| c.is_geographic())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Published coordinates of known points, from the EPSG guidance note
    /// 7-2 worked examples and the web-mercator definition.
    #[test]
    fn transforms_match_published_coordinates() {
        let wgs = Crs::wgs84();
        // Web Mercator: the antimeridian at the equator is half the equator's length
        let m = Crs::from_epsg(3857).unwrap();
        let p = wgs.point(&m, [180.0, 0.0]);
        assert!((p[0] - 20_037_508.342_789).abs() < 1e-3, "{p:?}");
        // latitude 85.0511287798° maps to the same northing
        let p = wgs.point(&m, [0.0, 85.051_128_779_8]);
        assert!((p[1] - 20_037_508.342_789).abs() < 0.01, "{p:?}");
        // UTM zone 31N (EPSG:32631): the central meridian 3°E at the equator is (500000, 0)
        let u = Crs::from_epsg(32631).unwrap();
        let p = wgs.point(&u, [3.0, 0.0]);
        assert!((p[0] - 500_000.0).abs() < 1e-6 && p[1].abs() < 1e-6, "{p:?}");
        // EPSG guidance note 7-2, transverse Mercator example (OSGB 1936 / British
        // National Grid, EPSG:27700): 50°30'N 0°30'E on the Airy ellipsoid is
        // E 577274.99, N 69740.50; the definition here shifts the datum too, so
        // that point is given in OSGB 1936 geographic coordinates (EPSG:4277)
        let osgb = Crs::from_epsg(4277).unwrap();
        let bng = Crs::from_epsg(27700).unwrap();
        let p = osgb.point(&bng, [0.5, 50.5]);
        assert!((p[0] - 577_274.99).abs() < 0.02 && (p[1] - 69_740.50).abs() < 0.02, "{p:?}");
        // and back
        let q = bng.point(&osgb, p);
        assert!((q[0] - 0.5).abs() < 1e-9 && (q[1] - 50.5).abs() < 1e-9, "{q:?}");
    }

    #[test]
    fn local_frame_is_metric_at_its_centre() {
        let wgs = Crs::wgs84();
        let l = Crs::local(-34.85, -8.0).unwrap();
        let c = wgs.point(&l, [-34.85, -8.0]);
        assert!(c[0].abs() < 1e-6 && c[1].abs() < 1e-6);
        assert!(!l.is_geographic() && wgs.is_geographic());
        assert_eq!(l.unit_metres(), 1.0);
    }

    #[test]
    fn unknown_codes_and_strings_are_refused_with_their_name() {
        let e = Crs::from_epsg(1).unwrap_err();
        assert_eq!(e, CrsError::UnknownEpsg(1));
        // a code too large for any table is unknown, not "not a number"
        assert_eq!(Crs::parse("EPSG:99999").unwrap_err(), CrsError::UnknownEpsg(99999));
        assert_eq!(Crs::parse("EPSG:4x").unwrap_err(), CrsError::BadEpsgCode("EPSG:4x".into()));
        assert!(e.to_string().contains("EPSG:1"), "{e}");
        let e = Crs::parse("UTM 33").unwrap_err();
        assert_eq!(e, CrsError::NotACrs("UTM 33".into()));
        assert!(e.to_string().contains("UTM 33"), "{e}");
        assert!(Crs::parse("EPSG:32633").is_ok());
        let e = Crs::parse("EPSG:x").unwrap_err();
        assert!(matches!(e, CrsError::BadEpsgCode(_)) && e.to_string().contains("EPSG:x"), "{e}");
        let e = Crs::local(0.0, 90.0).unwrap_err();
        assert!(matches!(e, CrsError::NoLocalFrame { .. }), "{e}");
        let e = Crs::from_definition("+proj=nosuch", "a test").unwrap_err();
        assert!(matches!(e, CrsError::Definition(_)), "{e}");
    }
}
