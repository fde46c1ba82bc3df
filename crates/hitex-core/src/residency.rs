//! Resident maps of a geospecific-texture pyramid (seed 001, eq. (5)–(7)).
//!
//! A frame needs, at each level, only the maps within the active area
//! around the point under the eye ([`active_maps`]). [`ResidentMaps`] keeps a
//! fixed budget of maps in memory, loads missing ones on a background
//! thread, evicts the least recently needed, and answers every lookup with
//! the nearest *resident* map at or above the requested level, so a frame
//! never has a hole: the single map of level 0 is loaded first and pinned.
//! A map that fails to load (missing or corrupt file) is reported once and
//! not asked for again; its coarser ancestors stand in for it.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A map of the pyramid: level `z` (0 coarsest), column `x`, row `y` from the north.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MapKey {
    /// Level, 0 the coarsest.
    pub z: u32,
    /// Column.
    pub x: u32,
    /// Row from the north.
    pub y: u32,
}

impl MapKey {
    /// The map one level coarser that contains this one.
    pub fn parent(self) -> Option<MapKey> {
        (self.z > 0).then(|| MapKey { z: self.z - 1, x: self.x / 2, y: self.y / 2 })
    }
}

/// Why a map could not be loaded: the loader's own error, whatever its type
/// (the cache logs it, by its `Display`, and lets a coarser map stand in).
pub type LoadError = Box<dyn std::error::Error + Send + Sync>;

/// Loads one map: RGBA8 texels, or why not.
pub type Loader = dyn Fn(MapKey) -> Result<Vec<u8>, LoadError> + Send + Sync;

/// What one frame asked of the cache.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Maps the active area needs.
    pub needed: usize,
    /// Maps in memory after this frame's completed loads and evictions.
    pub resident: usize,
    /// Loads requested this frame.
    pub requested: usize,
    /// Needed maps not resident yet (their ancestors stand in).
    pub missing: usize,
    /// Needed maps that failed to load earlier (ancestors stand in for good).
    pub failed: usize,
    /// Bytes of resident texels.
    pub bytes: usize,
}

/// The view of [`active_maps`]: field of view over a scanline, and the maps
/// per side of each level's square (eq. (7), from [`crate::terrain::active_area`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Field of view in degrees.
    pub fov_deg: f64,
    /// Pixels across it.
    pub pixels: u32,
    /// Maps per side of each level's square.
    pub per_side: u32,
}

/// The maps needed for an eye above ground point `eye` (finest-level
/// texels, x east, y south) at `altitude` (finest-level texels), a field of
/// view of `fov_deg` over `pixels` pixels: the square of `per_side` maps of
/// each level around the eye (eq. (7)), for every level coarse enough that
/// its texels are not smaller than a pixel's footprint at the nadir
/// (eq. (6) at x = 0), clipped to the maps holding data (`data_range(z)`:
/// first column, first row, one past the last of each).
pub fn active_maps(
    levels: u32,
    map_texels: u32,
    data_range: impl Fn(u32) -> [u32; 4],
    eye: [f64; 2],
    altitude: f64,
    view: View,
) -> Vec<MapKey> {
    let View { fov_deg, pixels, per_side } = view;
    if levels == 0 || !eye.iter().all(|v| v.is_finite()) || !altitude.is_finite() {
        return vec![MapKey { z: 0, x: 0, y: 0 }];
    }
    let k = pixels.max(1) as f64 / (2.0 * (fov_deg.clamp(1.0, 179.0).to_radians() / 2.0).tan());
    // pixel footprint at the nadir, in finest texels
    let foot = (altitude.abs().max(1e-6) / k).max(1e-6);
    let coarsening = foot.log2().floor().max(0.0) as u32;
    let z_max = (levels - 1).saturating_sub(coarsening);
    let mut out = Vec::new();
    for z in 0..=z_max {
        let span = map_texels as f64 * (1u64 << (levels - 1 - z)) as f64;
        let [c0, r0, c1, r1] = data_range(z);
        let (cx, cy) = (eye[0] / span, eye[1] / span);
        let half = per_side as f64 / 2.0;
        let (x0, y0) = ((cx - half).floor(), (cy - half).floor());
        for j in 0..per_side as i64 {
            for i in 0..per_side as i64 {
                let (x, y) = (x0 as i64 + i, y0 as i64 + j);
                if x >= c0 as i64 && y >= r0 as i64 && x < c1 as i64 && y < r1 as i64 {
                    out.push(MapKey { z, x: x as u32, y: y as u32 });
                }
            }
        }
    }
    if out.is_empty() {
        out.push(MapKey { z: 0, x: 0, y: 0 });
    }
    out
}

type Done = (MapKey, Result<Vec<u8>, LoadError>);

/// The resident-map cache.
pub struct ResidentMaps {
    budget: usize,
    maps: HashMap<MapKey, (Arc<Vec<u8>>, u64)>,
    pending: HashSet<MapKey>,
    failed: HashSet<MapKey>,
    to_worker: Option<Sender<MapKey>>,
    from_worker: Receiver<Done>,
    worker: Option<JoinHandle<()>>,
    frame: u64,
    log: Vec<String>,
}

const ROOT: MapKey = MapKey { z: 0, x: 0, y: 0 };

impl ResidentMaps {
    /// A cache of at most `budget` maps (at least 1) loading with `loader`;
    /// the level-0 map is loaded now and pinned — an error if it cannot be.
    pub fn new(budget: usize, loader: Arc<Loader>) -> Result<Self, crate::CoreError> {
        let root =
            loader(ROOT).map_err(|e| crate::CoreError::Residency(format!("the level-0 map cannot be loaded: {e}")))?;
        let (to_worker, requests) = channel::<MapKey>();
        let (done, from_worker) = channel::<Done>();
        let worker = std::thread::Builder::new()
            .name("hitex map loader".into())
            .spawn(move || {
                while let Ok(key) = requests.recv() {
                    let r = loader(key);
                    if done.send((key, r)).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| crate::CoreError::Residency(format!("cannot start the map loader: {e}")))?;
        let mut maps = HashMap::new();
        maps.insert(ROOT, (Arc::new(root), 0));
        Ok(Self {
            budget: budget.max(1),
            maps,
            pending: HashSet::new(),
            failed: HashSet::new(),
            to_worker: Some(to_worker),
            from_worker,
            worker: Some(worker),
            frame: 0,
            log: Vec::new(),
        })
    }

    fn integrate(&mut self, (key, r): Done) {
        self.pending.remove(&key);
        match r {
            Ok(t) => {
                self.maps.insert(key, (Arc::new(t), self.frame));
            }
            Err(e) => {
                if self.failed.insert(key) {
                    self.log.push(format!("map z{} x{} y{}: {e}; a coarser map stands in", key.z, key.x, key.y));
                }
            }
        }
    }

    /// Starts a frame needing `needed`: takes in finished loads, requests
    /// the missing maps (coarsest first, within the budget) and evicts the
    /// least recently needed maps beyond the budget.
    pub fn begin_frame(&mut self, needed: &[MapKey]) -> FrameStats {
        self.frame += 1;
        while let Ok(d) = self.from_worker.try_recv() {
            self.integrate(d);
        }
        let mut want: Vec<MapKey> = needed.to_vec();
        want.sort();
        want.dedup();
        let mut stats = FrameStats { needed: want.len(), ..Default::default() };
        for (i, key) in want.iter().enumerate() {
            if let Some(m) = self.maps.get_mut(key) {
                m.1 = self.frame;
                continue;
            }
            if self.failed.contains(key) {
                stats.failed += 1;
                continue;
            }
            stats.missing += 1;
            // never ask for more than the budget holds (coarse levels first)
            if !self.pending.contains(key)
                && i < self.budget
                && let Some(tx) = &self.to_worker
                && tx.send(*key).is_ok()
            {
                self.pending.insert(*key);
                stats.requested += 1;
            }
        }
        self.evict();
        stats.resident = self.maps.len();
        stats.bytes = self.maps.values().map(|m| m.0.len()).sum();
        stats
    }

    fn evict(&mut self) {
        if self.maps.len() + self.pending.len() <= self.budget {
            return;
        }
        let mut old: Vec<(u64, MapKey)> =
            self.maps.iter().filter(|(k, m)| **k != ROOT && m.1 < self.frame).map(|(k, m)| (m.1, *k)).collect();
        old.sort();
        let excess = (self.maps.len() + self.pending.len()).saturating_sub(self.budget);
        for (_, k) in old.into_iter().take(excess) {
            self.maps.remove(&k);
        }
    }

    /// The map to sample for `key`: itself if resident, else the nearest
    /// resident ancestor (the level-0 map at worst), with its key.
    pub fn lookup(&self, key: MapKey) -> (MapKey, Arc<Vec<u8>>) {
        let mut k = key;
        loop {
            if let Some(m) = self.maps.get(&k) {
                return (k, m.0.clone());
            }
            match k.parent() {
                Some(p) => k = p,
                None => break,
            }
        }
        // the root is pinned; an empty map only if it was never loaded
        (ROOT, self.maps.get(&ROOT).map(|m| m.0.clone()).unwrap_or_default())
    }

    /// Waits up to `timeout` for every requested load to finish.
    pub fn wait_pending(&mut self, timeout: Duration) {
        let end = Instant::now() + timeout;
        while !self.pending.is_empty() {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            match self.from_worker.recv_timeout(left) {
                Ok(d) => self.integrate(d),
                Err(_) => break,
            }
        }
    }

    /// Failures not reported yet (each map once).
    pub fn take_log(&mut self) -> Vec<String> {
        std::mem::take(&mut self.log)
    }

    /// Maps in memory.
    pub fn resident(&self) -> usize {
        self.maps.len()
    }
}

impl Drop for ResidentMaps {
    fn drop(&mut self) {
        // closing the channel ends the loader's loop
        self.to_worker = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loader(fail: Option<MapKey>) -> Arc<Loader> {
        Arc::new(move |k: MapKey| {
            if Some(k) == fail {
                return Err("corrupt PNG".into());
            }
            Ok(vec![k.z as u8, k.x as u8, k.y as u8, 255])
        })
    }

    fn tiles(levels: u32) -> impl Fn(u32) -> [u32; 4] {
        move |z| {
            let n = 1u32 << z.min(levels - 1);
            [0, 0, n, n]
        }
    }

    #[test]
    fn the_papers_setting_needs_at_most_324_maps() {
        // 9 levels, 45° over 1024 pixels: 6×6 maps per level
        let per = crate::terrain::active_area(45.0, 1024, 256, 9).unwrap()[0].per_side;
        assert_eq!(per, 6);
        let levels = 9;
        for alt in [50.0, 500.0, 5000.0, 50_000.0] {
            let m = active_maps(
                levels,
                256,
                tiles(levels),
                [30_000.0, 40_000.0],
                alt,
                View { fov_deg: 45.0, pixels: 1024, per_side: per },
            );
            assert!(m.len() <= 324, "{alt}: {}", m.len());
            assert!(m.contains(&ROOT));
        }
        // high up, only coarse levels are needed
        let high = active_maps(
            levels,
            256,
            tiles(levels),
            [30_000.0, 40_000.0],
            1e6,
            View { fov_deg: 45.0, pixels: 1024, per_side: per },
        );
        assert!(high.iter().all(|k| k.z <= 1));
        // the needed set does not depend on the source size beyond its levels
        let big =
            active_maps(20, 256, tiles(20), [1e7, 1e7], 500.0, View { fov_deg: 45.0, pixels: 1024, per_side: per });
        assert!(big.len() <= 6 * 6 * 20);
    }

    #[test]
    fn lookups_fall_back_and_loads_arrive() {
        let mut c = ResidentMaps::new(64, loader(None)).unwrap();
        let want = MapKey { z: 3, x: 5, y: 2 };
        let s = c.begin_frame(&[want, want.parent().unwrap()]);
        assert_eq!((s.needed, s.missing, s.requested), (2, 2, 2));
        // before the loads complete the root stands in
        let (k, _) = c.lookup(want);
        assert!(k.z <= 3);
        c.wait_pending(Duration::from_secs(5));
        let s = c.begin_frame(&[want]);
        assert_eq!(s.missing, 0);
        let (k, t) = c.lookup(want);
        assert_eq!((k, t[0], t[1], t[2]), (want, 3, 5, 2));
    }

    #[test]
    fn the_budget_holds_and_failures_are_logged_once() {
        let bad = MapKey { z: 2, x: 1, y: 1 };
        let mut c = ResidentMaps::new(10, loader(Some(bad))).unwrap();
        for f in 0..6u32 {
            let needed: Vec<MapKey> = (0..4).map(|i| MapKey { z: 2, x: (f + i) % 4, y: 1 }).collect();
            c.begin_frame(&needed);
            c.wait_pending(Duration::from_secs(5));
            let s = c.begin_frame(&needed);
            assert!(s.resident <= 10, "{s:?}");
        }
        let log = c.take_log();
        assert_eq!(log.len(), 1, "{log:?}");
        assert!(log[0].contains("corrupt"));
        // the failed map is served by its parent
        let (k, _) = c.lookup(bad);
        assert!(k.z < 2);
        assert!(c.take_log().is_empty());
    }

    #[test]
    fn a_missing_root_is_an_error() {
        assert!(ResidentMaps::new(4, loader(Some(ROOT))).is_err());
        // degenerate eyes still give a non-empty set
        assert_eq!(
            active_maps(5, 256, tiles(5), [f64::NAN, 0.0], 10.0, View { fov_deg: 45.0, pixels: 1024, per_side: 6 }),
            vec![ROOT]
        );
    }
}
