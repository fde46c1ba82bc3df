//! Flight paths: keys of position, altitude, pitch and heading over time,
//! read from TOML (`[[key]]` tables) and interpolated linearly between keys.
//!
//! ```toml
//! [[key]]
//! t = 0
//! x = 0.2          # east, fraction of the data's extent
//! y = 0.8          # south, fraction of the data's extent
//! altitude = 3000  # metres above the datum
//! pitch = 30       # degrees below the horizon (90 looks straight down)
//! heading = 45     # degrees clockwise from north
//! ```

use crate::CoreError;
use serde::Deserialize;

/// One key of a flight path.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathKey {
    /// Time (any unit; frames are spread evenly over the keys' range).
    pub t: f64,
    /// East position as a fraction of the extent.
    pub x: f64,
    /// South position as a fraction of the extent.
    pub y: f64,
    /// Altitude above the datum, metres: above the flat ground, or above the
    /// DEM's zero when the flight draws relief.
    pub altitude: f64,
    /// Pitch below the horizon, degrees (90 looks straight down).
    pub pitch: f64,
    /// Heading, degrees clockwise from north.
    pub heading: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PathFile {
    key: Vec<PathKey>,
}

/// A flight path: at least one key, checked and sorted by time.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightPath {
    keys: Vec<PathKey>,
}

impl FlightPath {
    /// A path through `keys` (any order): every value finite, the altitude
    /// above 0, x and y in 0 to 1, the pitch in (0, 90]. The error names the
    /// key by its index in `keys`.
    pub fn new(mut keys: Vec<PathKey>) -> Result<Self, CoreError> {
        let bad = |m: String| Err(CoreError::FlightPath(m));
        if keys.is_empty() {
            return bad("no [[key]] tables".into());
        }
        for (i, k) in keys.iter().enumerate() {
            let vals = [k.t, k.x, k.y, k.altitude, k.pitch, k.heading];
            if vals.iter().any(|v| !v.is_finite()) {
                return bad(format!("key[{i}] has a value that is not finite"));
            }
            if k.altitude <= 0.0 {
                return bad(format!("key[{i}].altitude = {}: the camera is below the ground", k.altitude));
            }
            if !(0.0..=1.0).contains(&k.x) || !(0.0..=1.0).contains(&k.y) {
                return bad(format!(
                    "key[{i}] at x = {}, y = {} is outside the store: x and y are fractions of its extent, in 0 to 1",
                    k.x, k.y
                ));
            }
            if !(k.pitch > 0.0 && k.pitch <= 90.0) {
                return bad(format!(
                    "key[{i}].pitch = {}° must be in (0, 90] below the horizon (90 looks straight down)",
                    k.pitch
                ));
            }
        }
        keys.sort_by(|a, b| a.t.total_cmp(&b.t));
        Ok(Self { keys })
    }

    /// Parses a path file's text (`[[key]]` tables, see the module).
    pub fn parse(text: &str) -> Result<Self, CoreError> {
        let f: PathFile =
            toml::from_str(text).map_err(|e| CoreError::Toml(crate::scene::desc::toml_message(text, &e)))?;
        Self::new(f.key)
    }

    /// The keys, sorted by time.
    pub fn keys(&self) -> &[PathKey] {
        &self.keys
    }

    /// The first and last key's times.
    pub fn span(&self) -> (f64, f64) {
        (self.keys[0].t, self.keys[self.keys.len() - 1].t)
    }

    /// The path at time `t`: the keys around it mixed linearly (held
    /// before the first key and after the last).
    pub fn at(&self, t: f64) -> PathKey {
        let keys = &self.keys;
        let i = keys.partition_point(|k| k.t <= t).clamp(1, keys.len()) - 1;
        let (a, b) = (keys[i], keys[(i + 1).min(keys.len() - 1)]);
        let s = if b.t > a.t { ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0) } else { 0.0 };
        let l = |p: f64, q: f64| p + (q - p) * s;
        PathKey {
            t,
            x: l(a.x, b.x),
            y: l(a.y, b.y),
            altitude: l(a.altitude, b.altitude),
            pitch: l(a.pitch, b.pitch),
            heading: l(a.heading, b.heading),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: f64, x: f64, altitude: f64) -> PathKey {
        PathKey { t, x, y: 0.5, altitude, pitch: 30.0, heading: 90.0 }
    }

    #[test]
    fn keys_are_sorted_and_mixed_linearly() {
        let p = FlightPath::new(vec![key(10.0, 0.9, 300.0), key(0.0, 0.1, 100.0)]).unwrap();
        assert_eq!(p.span(), (0.0, 10.0));
        let m = p.at(2.5);
        assert!((m.x - 0.3).abs() < 1e-12 && (m.altitude - 150.0).abs() < 1e-12, "{m:?}");
        // held outside the keys
        assert_eq!(p.at(-5.0).x, 0.1);
        assert_eq!(p.at(50.0).altitude, 300.0);
        // one key: everywhere that key
        let one = FlightPath::new(vec![key(3.0, 0.4, 200.0)]).unwrap();
        assert_eq!(one.at(0.0).x, 0.4);
        assert_eq!(one.at(7.0).altitude, 200.0);
    }

    #[test]
    fn parses_the_file_form() {
        let text = "[[key]]\nt = 0\nx = 0.2\ny = 0.8\naltitude = 3000\npitch = 30\nheading = 45\n\
                    [[key]]\nt = 1\nx = 0.4\ny = 0.6\naltitude = 2000\npitch = 60\nheading = 90\n";
        let p = FlightPath::parse(text).unwrap();
        assert_eq!(p.keys().len(), 2);
        assert!((p.at(0.5).pitch - 45.0).abs() < 1e-12);
    }

    #[test]
    fn bad_keys_are_refused_by_index() {
        let cases: [(PathKey, &str); 5] = [
            (PathKey { altitude: f64::NAN, ..key(0.0, 0.5, 1.0) }, "key[1] has a value that is not finite"),
            (key(0.0, 0.5, 0.0), "key[1].altitude = 0: the camera is below the ground"),
            (key(0.0, 1.5, 10.0), "key[1] at x = 1.5, y = 0.5 is outside the store"),
            (PathKey { pitch: 0.0, ..key(0.0, 0.5, 10.0) }, "key[1].pitch = 0° must be in (0, 90]"),
            (PathKey { pitch: 91.0, ..key(0.0, 0.5, 10.0) }, "key[1].pitch = 91° must be in (0, 90]"),
        ];
        for (bad, want) in cases {
            let e = FlightPath::new(vec![key(0.0, 0.5, 10.0), bad]).unwrap_err().to_string();
            assert!(e.starts_with(want), "{e}");
        }
        assert_eq!(FlightPath::new(vec![]).unwrap_err().to_string(), "no [[key]] tables");
        let e = FlightPath::parse("[[key]]\nt = 0\nx = 0.5\n").unwrap_err().to_string();
        assert!(e.contains("missing field"), "{e}");
        let e = FlightPath::parse("[[key]]\nt = 0\nx = 0.5\ny = 0.5\naltitude = 1\npitch = 9\nheading = 0\nroll = 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("roll"), "{e}");
    }
}
