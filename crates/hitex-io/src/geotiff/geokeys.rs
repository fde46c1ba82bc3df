//! The GeoKeys of a CRS, both ways: the user-defined projections read from
//! a file's keys as PROJ.4 definitions, and the keys that name a CRS when
//! a raster is written (its EPSG code, or user-defined keys).

/// GeoKeys of a user-defined projected CRS (ProjectedCSTypeGeoKey and
/// ProjectionGeoKey 32767, the method in ProjCoordTransGeoKey) as a PROJ.4
/// definition, for the methods elevation products use: transverse Mercator
/// (1), Mercator (7), Lambert conformal conic with two standard parallels
/// (8) and one (9), Lambert azimuthal equal-area (10), Albers equal-area
/// (11) and polar stereographic (15, variants A and B). The datum is that
/// of GeographicTypeGeoKey (an EPSG code; WGS 84 when absent), angles in
/// degrees, lengths in metres, feet or US survey feet
/// (ProjLinearUnitsGeoKey). Parameter keys as GDAL writes them, with the
/// natural-origin keys standing in for missing false-origin ones. Other
/// methods and units give None: the CRS is then named by its citation only.
pub(super) fn user_defined_projection(keys: &[u16], doubles: &[f64]) -> Option<String> {
    let entry = |id: u16| keys.chunks_exact(4).skip(1).find(|k| k[0] == id);
    let short = |id: u16| entry(id).filter(|k| k[1] == 0).map(|k| k[3]);
    let double = |id: u16| {
        entry(id)
            .filter(|k| k[1] == 34736 && k[2] == 1)
            .and_then(|k| doubles.get(k[3] as usize).copied())
            .filter(|v| v.is_finite())
    };
    if short(3072) != Some(32767) || short(3074) != Some(32767) {
        return None;
    }
    // angles in degrees only (GeogAngularUnitsGeoKey 9102)
    if !matches!(short(2054), None | Some(9102)) {
        return None;
    }
    // the datum of the geographic CRS: its definition without the method
    let datum = match short(2048) {
        None | Some(4326) => "+datum=WGS84".to_string(),
        Some(code) => {
            let def = crs_definitions::from_code(code)?.proj4;
            let rest = def.strip_prefix("+proj=longlat ")?;
            rest.split_whitespace().filter(|p| !matches!(*p, "+no_defs" | "+type=crs")).collect::<Vec<_>>().join(" ")
        }
    };
    let (units, metres) = match short(3076) {
        None | Some(9001) => ("m", 1.0),
        Some(9002) => ("ft", 0.3048),
        Some(9003) => ("us-ft", 1200.0 / 3937.0),
        Some(_) => return None,
    };
    // a key, else its stand-in
    let either = |a: u16, b: u16| double(a).or_else(|| double(b));
    let lat_ok = |v: f64| v.abs() <= 90.0;
    // false easting and northing in metres (PROJ's +x_0, +y_0 are metres whatever +units)
    let offsets = |e: u16, n: u16| (either(e, 3082).unwrap_or(0.0) * metres, either(n, 3083).unwrap_or(0.0) * metres);
    let (method, (fe, fn_)) = match short(3075)? {
        1 => {
            let (lon, lat, k) = (double(3080)?, double(3081)?, double(3092).unwrap_or(1.0));
            if !(lat_ok(lat) && lat.abs() < 90.0 && k > 0.0) {
                return None;
            }
            let (fe, fn_) = offsets(3082, 3083);
            if datum == "+datum=WGS84" && units == "m" {
                // the form a local metric frame is written in (read back equal)
                return Some(crate::crs::tm_definition(lon, lat, k, fe, fn_));
            }
            (format!("+proj=tmerc +lat_0={lat} +lon_0={lon} +k={k}"), (fe, fn_))
        }
        7 => {
            let lon = double(3080).or_else(|| double(3088))?;
            // Mercator (2SP) by its standard parallel, (1SP) by its scale
            let m = match double(3078) {
                Some(ts) if lat_ok(ts) && ts.abs() < 90.0 => format!("+proj=merc +lon_0={lon} +lat_ts={ts}"),
                _ => format!("+proj=merc +lon_0={lon} +k={}", double(3092).unwrap_or(1.0)),
            };
            (m, offsets(3082, 3083))
        }
        8 | 11 => {
            let (p1, p2) = (double(3078)?, double(3079)?);
            let (lat0, lon0) = (either(3085, 3081)?, either(3084, 3080)?);
            if ![p1, p2, lat0].iter().all(|v| lat_ok(*v)) {
                return None;
            }
            let name = if short(3075) == Some(8) { "lcc" } else { "aea" };
            (format!("+proj={name} +lat_1={p1} +lat_2={p2} +lat_0={lat0} +lon_0={lon0}"), offsets(3086, 3087))
        }
        9 => {
            let (lat0, lon0, k) = (double(3081)?, double(3080)?, double(3092).unwrap_or(1.0));
            if !(lat_ok(lat0) && lat0 != 0.0 && k > 0.0) {
                return None;
            }
            (format!("+proj=lcc +lat_1={lat0} +lat_0={lat0} +lon_0={lon0} +k={k}"), offsets(3082, 3083))
        }
        10 => {
            let (lat0, lon0) = (either(3089, 3081)?, either(3088, 3080)?);
            if !lat_ok(lat0) {
                return None;
            }
            (format!("+proj=laea +lat_0={lat0} +lon_0={lon0}"), offsets(3082, 3083))
        }
        15 => {
            let lat = double(3081)?;
            let lon0 = either(3095, 3080)?;
            if !(lat_ok(lat) && lat != 0.0) {
                return None;
            }
            let pole = if lat > 0.0 { 90 } else { -90 };
            // variant A: origin at the pole, a scale there; variant B: the
            // latitude of true scale
            let m = if lat.abs() == 90.0 {
                format!("+proj=stere +lat_0={pole} +lon_0={lon0} +k={}", double(3092).unwrap_or(1.0))
            } else {
                format!("+proj=stere +lat_0={pole} +lat_ts={lat} +lon_0={lon0}")
            };
            (m, offsets(3082, 3083))
        }
        _ => return None,
    };
    Some(format!("{method} +x_0={fe} +y_0={fn_} +units={units} {datum} +no_defs"))
}

/// Geographic CRSs whose datum a user-defined projection may be written
/// on (GeographicTypeGeoKey): WGS 84, NAD83, ETRS89, RGF93, GDA94,
/// GDA2020, JGD2000, NZGD2000, OSGB 1936, NAD27-era Clarke 1866 (JAD69),
/// Makassar (Bessel).
const GEOGRAPHIC_CODES: [u16; 11] = [4326, 4269, 4258, 4171, 4283, 7844, 4612, 4167, 4277, 4242, 4257];

/// A GeoKey and its value in the directory.
type ShortKey = (u16, u16);
/// A GeoKey and its value in GeoDoubleParams.
type DoubleKey = (u16, f64);

/// The GeoKeys (short keys, double keys) that describe a PROJ.4 definition
/// of one of the projections [`user_defined_projection`] reads, so that a
/// DEM written in it reads back in the same CRS; None for any other.
fn user_defined_keys(def: &str) -> Option<(Vec<ShortKey>, Vec<DoubleKey>)> {
    let mut p: std::collections::BTreeMap<&str, &str> = std::collections::BTreeMap::new();
    let mut datum = Vec::new();
    for part in def.split_whitespace() {
        let (k, v) = part.strip_prefix('+')?.split_once('=').unwrap_or((part.trim_start_matches('+'), ""));
        match k {
            "datum" | "ellps" | "towgs84" | "a" | "b" | "rf" | "nadgrids" | "pm" => datum.push(part),
            "no_defs" | "type" => {}
            _ => {
                p.insert(k, v);
            }
        }
    }
    let datum = datum.join(" ");
    let geog = GEOGRAPHIC_CODES.into_iter().find(|&c| {
        let d = crs_definitions::from_code(c).map(|d| d.proj4).unwrap_or("");
        let rest: Vec<&str> = d
            .strip_prefix("+proj=longlat ")
            .unwrap_or("")
            .split_whitespace()
            .filter(|x| !matches!(*x, "+no_defs" | "+type=crs"))
            .collect();
        rest.join(" ") == datum
    })?;
    let num = |k: &str| p.get(k).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite());
    let (unit, metres) = match p.get("units").copied() {
        None | Some("m") => (9001, 1.0),
        Some("ft") => (9002, 0.3048),
        Some("us-ft") => (9003, 1200.0 / 3937.0),
        Some(_) => return None,
    };
    let (lon0, lat0) = (num("lon_0").unwrap_or(0.0), num("lat_0").unwrap_or(0.0));
    let (fe, fn_) = (num("x_0").unwrap_or(0.0) / metres, num("y_0").unwrap_or(0.0) / metres);
    let k = num("k").or_else(|| num("k0")).unwrap_or(1.0);
    let known = |keys: &[&str]| p.keys().all(|k| keys.contains(k));
    let (method, mut d): (u16, Vec<(u16, f64)>) = match *p.get("proj")? {
        "tmerc" if known(&["proj", "lon_0", "lat_0", "k", "k0", "x_0", "y_0", "units"]) => {
            (1, vec![(3080, lon0), (3081, lat0), (3092, k), (3082, fe), (3083, fn_)])
        }
        "merc" if known(&["proj", "lon_0", "lat_ts", "k", "k0", "x_0", "y_0", "units"]) => match num("lat_ts") {
            Some(ts) => (7, vec![(3080, lon0), (3078, ts), (3082, fe), (3083, fn_)]),
            None => (7, vec![(3080, lon0), (3092, k), (3082, fe), (3083, fn_)]),
        },
        m @ ("lcc" | "aea")
            if known(&["proj", "lon_0", "lat_0", "lat_1", "lat_2", "k", "k0", "x_0", "y_0", "units"]) =>
        {
            let p1 = num("lat_1")?;
            match num("lat_2") {
                Some(p2) if m == "aea" || p2 != p1 => (
                    if m == "lcc" { 8 } else { 11 },
                    vec![(3078, p1), (3079, p2), (3085, lat0), (3084, lon0), (3086, fe), (3087, fn_)],
                ),
                // one standard parallel: the latitude of origin (1SP)
                _ if m == "lcc" && p1 == lat0 => {
                    (9, vec![(3081, lat0), (3080, lon0), (3092, k), (3082, fe), (3083, fn_)])
                }
                _ => return None,
            }
        }
        "laea" if known(&["proj", "lon_0", "lat_0", "x_0", "y_0", "units"]) => {
            (10, vec![(3089, lat0), (3088, lon0), (3082, fe), (3083, fn_)])
        }
        "stere"
            if known(&["proj", "lon_0", "lat_0", "lat_ts", "k", "k0", "x_0", "y_0", "units"]) && lat0.abs() == 90.0 =>
        {
            match num("lat_ts").filter(|t| t.abs() != 90.0) {
                Some(ts) if ts.signum() == lat0.signum() => {
                    (15, vec![(3081, ts), (3095, lon0), (3082, fe), (3083, fn_)])
                }
                Some(_) => return None,
                None => (15, vec![(3081, lat0), (3095, lon0), (3092, k), (3082, fe), (3083, fn_)]),
            }
        }
        _ => return None,
    };
    d.sort_by_key(|e| e.0);
    let shorts = vec![(2048, geog), (3072, 32767), (3074, 32767), (3075, method), (3076, unit)];
    Some((shorts, d))
}

/// The GeoKeys of a CRS: the key directory (PixelIsArea), its double
/// parameters and its citation (GeoAsciiParams).
pub(crate) struct GeoKeys {
    pub(crate) dir: Vec<u16>,
    pub(crate) doubles: Vec<f64>,
    pub(crate) citation: String,
}

/// The GeoKeys that name `crs`: its EPSG code, or user-defined keys.
pub(crate) fn geokeys(crs: &crate::crs::Crs) -> Result<GeoKeys, String> {
    let werr = |m: String| m;
    let mut keys: Vec<u16> = Vec::new();
    let mut doubles: Vec<f64> = Vec::new();
    let geographic = crs.is_geographic();
    // the CRS's name as the citation (GTCitationGeoKey in GeoAsciiParams)
    let citation: String = crs.name().replace('°', " deg").chars().filter(|c| c.is_ascii() && *c != '|').collect();
    let citation = format!("{citation}|");
    let cite_len = u16::try_from(citation.len()).map_err(|_| werr("the CRS's name is too long".into()))?;
    keys.extend_from_slice(&[1024, 0, 1, if geographic { 2 } else { 1 }, 1025, 0, 1, 1, 1026, 34737, cite_len, 0]);
    match crs.epsg() {
        Some(c) => keys.extend_from_slice(&[if geographic { 2048 } else { 3072 }, 0, 1, c]),
        None => {
            let Some((shorts, params)) = user_defined_keys(crs.definition()) else {
                return Err(werr(format!(
                    "{} has no EPSG code and is not a projection GeoKeys can describe (transverse Mercator, \
                     Mercator, Lambert conformal conic, Lambert azimuthal equal-area, Albers or polar \
                     stereographic on the datum of a geographic EPSG code, in metres or feet)",
                    crs.name()
                )));
            };
            // keys in ascending order, as the directory requires
            let mut all: Vec<(u16, Option<u16>, f64)> = shorts.iter().map(|&(id, v)| (id, Some(v), 0.0)).collect();
            all.extend(params.iter().map(|&(id, v)| (id, None, v)));
            all.sort_by_key(|e| e.0);
            for (id, short, v) in all {
                match short {
                    Some(x) => keys.extend_from_slice(&[id, 0, 1, x]),
                    None => {
                        keys.extend_from_slice(&[id, 34736, 1, doubles.len() as u16]);
                        doubles.push(v);
                    }
                }
            }
        }
    }
    let mut dir = vec![1u16, 1, 0, (keys.len() / 4) as u16];
    dir.extend_from_slice(&keys);
    Ok(GeoKeys { dir, doubles, citation })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A GeoKey directory of a user-defined projection: short keys, then
    /// double keys (values in GeoDoubleParams order).
    fn user_keys(shorts: &[(u16, u16)], doubles: &[(u16, f64)]) -> (Vec<u16>, Vec<f64>) {
        let mut k = vec![1u16, 1, 0, (shorts.len() + doubles.len() + 2) as u16, 3072, 0, 1, 32767, 3074, 0, 1, 32767];
        for (id, v) in shorts {
            k.extend_from_slice(&[*id, 0, 1, *v]);
        }
        for (i, (id, _)) in doubles.iter().enumerate() {
            k.extend_from_slice(&[*id, 34736, 1, i as u16]);
        }
        (k, doubles.iter().map(|d| d.1).collect())
    }

    /// The projected coordinates of `lon_lat` (in the geographic CRS of
    /// EPSG code `geog`) under the user-defined projection of the keys.
    fn project(shorts: &[(u16, u16)], doubles: &[(u16, f64)], geog: u16, lon_lat: [f64; 2]) -> [f64; 2] {
        let (k, d) = user_keys(shorts, doubles);
        let def = user_defined_projection(&k, &d).expect("a supported projection");
        let crs = crate::crs::Crs::from_definition(&def, "test").unwrap();
        crate::crs::Crs::from_epsg(geog).unwrap().point(&crs, lon_lat)
    }

    /// The worked examples of EPSG Guidance Note 7-2 (coordinate conversions
    /// and transformations), entered as the GeoKeys a user-defined
    /// projection carries: every method the reader maps, on the ellipsoids,
    /// units and parameter keys of those examples.
    #[test]
    fn user_defined_projections_match_the_epsg_worked_examples() {
        let dms = |d: f64, m: f64, s: f64| d.signum() * (d.abs() + m / 60.0 + s / 3600.0);
        let close = |p: [f64; 2], e: [f64; 2], tol: f64| {
            assert!((p[0] - e[0]).abs() < tol && (p[1] - e[1]).abs() < tol, "{p:?}, expected {e:?}");
        };
        // Lambert conic conformal (2SP), NAD27 / Texas South Central on Clarke
        // 1866 (here through JAD69's Clarke 1866, no datum shift), US survey feet
        let p = project(
            &[(3075, 8), (2048, 4242), (3076, 9003)],
            &[
                (3078, dms(28.0, 23.0, 0.0)),
                (3079, dms(30.0, 17.0, 0.0)),
                (3085, dms(27.0, 50.0, 0.0)),
                (3084, -99.0),
                (3086, 2_000_000.0),
                (3087, 0.0),
            ],
            4242,
            [-96.0, 28.5],
        );
        close(p, [2_963_503.91, 254_759.80], 0.05);
        // Lambert conic conformal (1SP), JAD69 / Jamaica National Grid
        let p = project(
            &[(3075, 9), (2048, 4242)],
            &[(3081, 18.0), (3080, -77.0), (3092, 1.0), (3082, 250_000.0), (3083, 150_000.0)],
            4242,
            [dms(-76.0, 56.0, 37.26), dms(17.0, 55.0, 55.80)],
        );
        close(p, [255_966.58, 142_493.51], 0.02);
        // Lambert azimuthal equal area, ETRS89 / LAEA Europe (GRS 1980)
        let p = project(
            &[(3075, 10), (2048, 4258)],
            &[(3089, 52.0), (3088, 10.0), (3082, 4_321_000.0), (3083, 3_210_000.0)],
            4258,
            [5.0, 50.0],
        );
        close(p, [3_962_799.45, 2_999_718.85], 0.02);
        // Mercator (1SP), Makassar / NEIEZ (Bessel 1841)
        let p = project(
            &[(3075, 7), (2048, 4257)],
            &[(3080, 110.0), (3092, 0.997), (3082, 3_900_000.0), (3083, 900_000.0)],
            4257,
            [120.0, -3.0],
        );
        close(p, [5_009_726.58, 569_150.82], 0.02);
        // polar stereographic (variant A), WGS 84 / UPS North
        let p = project(
            &[(3075, 15), (2048, 4326)],
            &[(3081, 90.0), (3095, 0.0), (3092, 0.994), (3082, 2_000_000.0), (3083, 2_000_000.0)],
            4326,
            [44.0, 73.0],
        );
        close(p, [3_320_416.75, 632_668.43], 0.02);
        // polar stereographic (variant B), WGS 84 / Australian Antarctic Polar Stereographic
        let p = project(
            &[(3075, 15)],
            &[(3081, -71.0), (3095, 70.0), (3082, 6_000_000.0), (3083, 6_000_000.0)],
            4326,
            [120.0, -75.0],
        );
        close(p, [7_255_380.79, 7_053_389.56], 0.02);
        // Albers equal area: the same point as EPSG:5070 (NAD83 / Conus Albers) puts it
        let keys = [(3078, 29.5), (3079, 45.5), (3085, 23.0), (3084, -96.0), (3086, 0.0), (3087, 0.0)];
        let p = project(&[(3075, 11), (2048, 4269)], &keys, 4269, [-100.0, 40.0]);
        let q =
            crate::crs::Crs::from_epsg(4269).unwrap().point(&crate::crs::Crs::from_epsg(5070).unwrap(), [-100.0, 40.0]);
        close(p, q, 1e-6);
        // transverse Mercator off WGS 84: OSGB 1936 / British National Grid
        let p = project(
            &[(3075, 1), (2048, 4277)],
            &[(3081, 49.0), (3080, -2.0), (3092, 0.999_601_271_7), (3082, 400_000.0), (3083, -100_000.0)],
            4277,
            [0.5, 50.5],
        );
        close(p, [577_274.99, 69_740.50], 0.02);
    }

    #[test]
    fn user_defined_projections_outside_the_methods_read_are_left_unnamed() {
        // oblique Mercator (3): not mapped
        let (k, d) = user_keys(&[(3075, 3)], &[(3081, 4.0), (3080, 115.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // grads (9105) as the angular unit
        let (k, d) = user_keys(&[(3075, 9), (2054, 9105)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // a linear unit other than metre and feet (9004: chain, say)
        let (k, d) = user_keys(&[(3075, 9), (3076, 9004)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // a missing parameter, a latitude past the pole
        let (k, d) = user_keys(&[(3075, 8)], &[(3078, 30.0), (3085, 20.0), (3084, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        let (k, d) = user_keys(&[(3075, 10)], &[(3081, 95.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // an unknown geographic CRS
        let (k, d) = user_keys(&[(3075, 9), (2048, 1)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
    }
}
