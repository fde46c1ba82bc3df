//! The codes of the choices the fragment programs receive in their
//! uniforms — texture filter, wrap, level rule, display mode, tone map,
//! flight sampler — as WGSL constants generated from the Rust tables
//! ([`Filter::ALL`], [`Wrap::ALL`], [`LevelRule::ALL`], [`RenderMode::ALL`],
//! [`ToneMap::ALL`], [`FlySampler::ALL`]) and prepended to every shader, so
//! that no code is written twice. (The NURBS display modes and flags have
//! their own table, [`crate::nurbs::wgsl_mode_constants`].)

use crate::terrain::FlySampler;
use hitex_core::scene::RenderMode;
use hitex_core::texture::{Filter, LevelRule, ToneMap, Wrap};

/// Every code as a WGSL constant `<CHOICE>_<NAME>`: `FILTER_NEAREST`,
/// `WRAP_MIRROR`, `LEVEL_RULE_VULKAN_RHO`, `RENDER_UV`, `TONE_ACES`,
/// `SAMPLER_SPAN3`, … (the name in capitals, `-` as `_`).
pub fn wgsl_constants() -> String {
    let mut s = String::new();
    for (choice, name, code) in table() {
        s += &format!("const {choice}_{}: u32 = {code}u;\n", name.to_ascii_uppercase().replace('-', "_"));
    }
    s
}

/// (choice, name, code) of every constant of [`wgsl_constants`].
pub fn table() -> Vec<(&'static str, &'static str, u32)> {
    let mut t = Vec::new();
    t.extend(Filter::ALL.iter().map(|&(n, f)| ("FILTER", n, f.code())));
    t.extend(Wrap::ALL.iter().map(|&(n, w)| ("WRAP", n, w.code())));
    t.extend(LevelRule::ALL.iter().map(|&(n, r)| ("LEVEL_RULE", n, r.code())));
    t.extend(RenderMode::ALL.iter().map(|&(n, m)| ("RENDER", n, m.index())));
    t.extend(ToneMap::ALL.iter().map(|&m| ("TONE", m.name(), m.code())));
    t.extend(FlySampler::ALL.iter().map(|&s| ("SAMPLER", s.name(), s.code())));
    t
}
