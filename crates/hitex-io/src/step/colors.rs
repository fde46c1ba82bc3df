//! Face colours from presentation styles: a `STYLED_ITEM` (or
//! `OVER_RIDING_STYLED_ITEM`) names an item (a face, a shell, a solid) and
//! styles that lead, through surface style usages, side styles and fill
//! areas, to a `COLOUR_RGB` or a `DRAUGHTING_PRE_DEFINED_COLOUR`. A face takes
//! its own colour, else its shell's, else its solid's. Curve styles (edge
//! colours) are not surface colours and are skipped.

use super::part21::{Param, Record};
use std::collections::{HashMap, HashSet};

/// Deepest chain of style records followed from a styled item.
const MAX_STYLE_DEPTH: usize = 12;

/// Colours of faces (linear RGB), by face `#` number.
pub(crate) fn face_colors(records: &HashMap<u64, Record>) -> HashMap<u64, [f32; 3]> {
    let mut item_color: HashMap<u64, [f32; 3]> = HashMap::new();
    let mut ids: Vec<&u64> = records.keys().collect();
    ids.sort();
    for id in &ids {
        let r = &records[id];
        let Some(p) = r.part("STYLED_ITEM").or_else(|| r.part("OVER_RIDING_STYLED_ITEM")) else { continue };
        let (Some(styles), Some(item)) = (p.get(1), p.get(2).and_then(Param::reference)) else { continue };
        let mut seen = HashSet::new();
        if let Some(c) = find_colour(records, styles, 0, &mut seen) {
            // an overriding style wins over a plain one
            if r.is("OVER_RIDING_STYLED_ITEM") || !item_color.contains_key(&item) {
                item_color.insert(item, c);
            }
        }
    }
    if item_color.is_empty() {
        return HashMap::new();
    }
    // faces of shells, shells of solids and surface models
    let mut out: HashMap<u64, [f32; 3]> = HashMap::new();
    let list = |r: &Record, k: usize| -> Vec<u64> {
        match r.parts[0].1.get(k) {
            Some(Param::Ref(x)) => vec![*x],
            Some(Param::List(l)) => l.iter().filter_map(Param::reference).collect(),
            _ => vec![],
        }
    };
    let mut shell_color: HashMap<u64, [f32; 3]> = HashMap::new();
    for id in &ids {
        let r = &records[id];
        let shells = match r.parts[0].0.as_str() {
            "MANIFOLD_SOLID_BREP" | "FACETED_BREP" | "SHELL_BASED_SURFACE_MODEL" | "FACE_BASED_SURFACE_MODEL" => {
                list(r, 1)
            }
            "BREP_WITH_VOIDS" => [list(r, 1), list(r, 2)].concat(),
            _ => continue,
        };
        if let Some(c) = item_color.get(id) {
            for s in shells {
                shell_color.entry(s).or_insert(*c);
            }
        }
    }
    for id in &ids {
        let r = &records[id];
        if !matches!(r.parts[0].0.as_str(), "CLOSED_SHELL" | "OPEN_SHELL" | "CONNECTED_FACE_SET") {
            continue;
        }
        let shell = item_color.get(id).or_else(|| shell_color.get(id)).copied();
        for f in list(r, 1) {
            if let Some(c) = item_color.get(&f).copied().or(shell) {
                out.insert(f, c);
            }
        }
    }
    // faces styled directly but in no shell read above
    for (item, c) in &item_color {
        if records.get(item).is_some_and(|r| r.is("ADVANCED_FACE") || r.is("FACE_SURFACE")) {
            out.insert(*item, *c);
        }
    }
    out
}

/// The first surface colour reachable from a style parameter.
fn find_colour(records: &HashMap<u64, Record>, p: &Param, depth: usize, seen: &mut HashSet<u64>) -> Option<[f32; 3]> {
    if depth > MAX_STYLE_DEPTH {
        return None;
    }
    match p {
        Param::List(l) => l.iter().find_map(|x| find_colour(records, x, depth + 1, seen)),
        Param::Typed(_, x) => find_colour(records, x, depth + 1, seen),
        Param::Ref(id) => {
            if !seen.insert(*id) {
                return None;
            }
            let r = records.get(id)?;
            if let Some(c) = r.part("COLOUR_RGB") {
                let v: Vec<f32> = c.iter().skip(1).filter_map(Param::number).map(|x| x as f32).collect();
                return (v.len() == 3 && v.iter().all(|x| x.is_finite()))
                    .then(|| [0, 1, 2].map(|k| hitex_core::texture::srgb_to_linear(v[k].clamp(0.0, 1.0))));
            }
            if let Some(c) = r.part("DRAUGHTING_PRE_DEFINED_COLOUR") {
                return named(c.first().and_then(Param::text)?);
            }
            // edge colours are not the face's
            if r.is("CURVE_STYLE") || r.is("POINT_STYLE") {
                return None;
            }
            r.parts.iter().flat_map(|(_, ps)| ps.iter()).find_map(|x| find_colour(records, x, depth + 1, seen))
        }
        _ => None,
    }
}

/// The colours ISO 10303-46 predefines, in linear RGB.
fn named(name: &str) -> Option<[f32; 3]> {
    Some(match name.to_ascii_lowercase().as_str() {
        "red" => [1.0, 0.0, 0.0],
        "green" => [0.0, 1.0, 0.0],
        "blue" => [0.0, 0.0, 1.0],
        "yellow" => [1.0, 1.0, 0.0],
        "magenta" => [1.0, 0.0, 1.0],
        "cyan" => [0.0, 1.0, 1.0],
        "black" => [0.0, 0.0, 0.0],
        "white" => [1.0, 1.0, 1.0],
        _ => return None,
    })
}
