//! A texture-cache model: what the paper calls *load efficiency* (Fig. 6).
//!
//! The paper finds that read counts alone do not decide speed: how often a
//! read hits the texture cache does, i.e. how close the texels of
//! neighbouring pixels lie in memory. The model is a set-associative LRU
//! cache whose lines are 4×4-texel blocks of one layer — 64 bytes of RGBA8,
//! or one 8-byte BC1 block, the unit a GPU fetches for compressed textures.
//! It is fed with the texels every read of the CPU twin touches (the
//! hardware footprint: 1, 4 or 8 texels), in the order the pixels are shaded.

use super::layout::FetchSink;
use crate::CoreError;

/// Cache geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CacheConfig {
    /// Capacity in bytes.
    pub bytes: u32,
    /// Associativity (lines per set).
    pub ways: u32,
    /// True when the texture is BC1: a line is one 8-byte block instead of 64 bytes.
    pub bc1: bool,
}

impl Default for CacheConfig {
    /// 16 KiB, 4-way: the order of a 2005 GPU's L1 texture cache.
    fn default() -> Self {
        Self { bytes: 16 << 10, ways: 4, bc1: false }
    }
}

impl CacheConfig {
    /// Bytes of one line (one 4×4 block).
    pub fn line_bytes(&self) -> u32 {
        if self.bc1 { 8 } else { 64 }
    }
}

/// The cache and its counters.
#[derive(Debug, Clone)]
pub struct CacheModel {
    config: CacheConfig,
    sets: usize,
    /// `sets × ways` tags (u64::MAX = empty), most recent first within a set.
    tags: Vec<u64>,
    blocks_w: u64,
    blocks_h: u64,
    /// Texture instructions.
    pub reads: u64,
    /// Texel accesses.
    pub accesses: u64,
    /// Accesses that hit.
    pub hits: u64,
    last: u64,
}

impl CacheModel {
    /// A cold cache for a texture of `width`×`height` texels per layer.
    pub fn new(config: CacheConfig, width: u32, height: u32) -> Result<Self, CoreError> {
        let lines = config.bytes / config.line_bytes();
        if config.ways == 0 || lines == 0 || !lines.is_multiple_of(config.ways) {
            return Err(CoreError::OutOfRange {
                key: "cache".into(),
                message: format!(
                    "{} bytes of {}-byte lines cannot form {}-way sets",
                    config.bytes,
                    config.line_bytes(),
                    config.ways
                ),
            });
        }
        let sets = (lines / config.ways) as usize;
        Ok(Self {
            config,
            sets,
            tags: vec![u64::MAX; sets * config.ways as usize],
            blocks_w: width.div_ceil(4) as u64,
            blocks_h: height.div_ceil(4) as u64,
            reads: 0,
            accesses: 0,
            hits: 0,
            last: u64::MAX,
        })
    }

    /// Hit rate in [0, 1].
    pub fn hit_rate(&self) -> f64 {
        if self.accesses == 0 { 0.0 } else { self.hits as f64 / self.accesses as f64 }
    }

    /// Bytes fetched from memory (misses × line size).
    pub fn bytes_fetched(&self) -> u64 {
        (self.accesses - self.hits) * self.config.line_bytes() as u64
    }

    fn access(&mut self, line: u64) {
        self.accesses += 1;
        // the four texels of one bilinear footprint mostly share a line
        if line == self.last {
            self.hits += 1;
            return;
        }
        self.last = line;
        // set index from a mix of the line number (breaks power-of-two aliasing)
        let set = ((line ^ (line >> 7) ^ (line >> 15)) % self.sets as u64) as usize;
        let ways = self.config.ways as usize;
        let slot = &mut self.tags[set * ways..(set + 1) * ways];
        match slot.iter().position(|&t| t == line) {
            Some(i) => {
                self.hits += 1;
                slot[..=i].rotate_right(1);
            }
            None => {
                slot.rotate_right(1);
                slot[0] = line;
            }
        }
    }
}

impl FetchSink for CacheModel {
    fn read(&mut self) {
        self.reads += 1;
    }
    fn texel(&mut self, x: u32, y: u32, z: u32) {
        let line = (z as u64 * self.blocks_h + (y / 4) as u64) * self.blocks_w + (x / 4) as u64;
        self.access(line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_texels_hit() {
        let mut c = CacheModel::new(CacheConfig::default(), 64, 64).unwrap();
        for _ in 0..10 {
            for y in 0..4 {
                for x in 0..4 {
                    c.texel(x, y, 0);
                }
            }
        }
        assert_eq!(c.accesses, 160);
        assert_eq!(c.hits, 159);
        assert_eq!(c.bytes_fetched(), 64);
    }

    #[test]
    fn a_stream_larger_than_the_cache_misses() {
        let cfg = CacheConfig { bytes: 1024, ways: 2, bc1: false };
        let mut c = CacheModel::new(cfg, 4096, 4096).unwrap();
        for pass in 0..2 {
            for b in 0..1024u32 {
                c.texel((b % 1024) * 4, (b / 1024) * 4, 0);
            }
            if pass == 0 {
                assert_eq!(c.hits, 0);
            }
        }
        // 1024 distinct lines through a 16-line cache: no reuse survives
        assert!(c.hit_rate() < 0.05, "{}", c.hit_rate());
        // with BC1 lines (8 B) the same cache holds 128 lines: the same stream of 64 lines reuses
        let cfg = CacheConfig { bytes: 1024, ways: 2, bc1: true };
        let mut c = CacheModel::new(cfg, 4096, 4096).unwrap();
        for _ in 0..2 {
            for b in 0..64u32 {
                c.texel(b * 4, 0, 0);
            }
        }
        assert!(c.hit_rate() > 0.45, "{}", c.hit_rate());
    }

    #[test]
    fn bad_geometry_is_refused() {
        assert!(CacheModel::new(CacheConfig { bytes: 100, ways: 4, bc1: false }, 4, 4).is_err());
        assert!(CacheModel::new(CacheConfig { bytes: 1024, ways: 0, bc1: false }, 4, 4).is_err());
    }
}
