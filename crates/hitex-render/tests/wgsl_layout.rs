//! Every uniform block the backends share: the Rust `#[repr(C)]` struct and
//! the WGSL struct the shader declares have the same size and the same
//! member offsets (WGSL's uniform layout rules, as naga's front end computes
//! them), so that a field added on one side only fails here, not as a
//! garbled frame.

use hitex_core::btf::Layout;
use hitex_render::btf::BtfFrame;
use hitex_render::gpu::{layout_source, nurbs_source, terrain_source, textured_source};
use hitex_render::nurbs::NurbsFrame;
use hitex_render::prepare::{FrameUniform, LightUniform, MaterialUniform};
use hitex_render::terrain::FlyUniform;
use std::mem::{offset_of, size_of};

/// The size and the (member, offset) list of struct `name` in `source`.
fn wgsl_struct(source: &str, name: &str) -> (usize, Vec<(String, usize)>) {
    let module =
        naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the shader"))
        .1;
    match &ty.inner {
        naga::TypeInner::Struct { members, span } => {
            (*span as usize, members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize)).collect())
        }
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

/// Checks `rust` (Rust size, (WGSL member, Rust offset) in declaration order)
/// against the WGSL struct `name` of `source`.
fn check(source: &str, name: &str, rust_size: usize, rust: &[(&str, usize)]) {
    let (size, members) = wgsl_struct(source, name);
    let names: Vec<&str> = members.iter().map(|m| m.0.as_str()).collect();
    let expect: Vec<&str> = rust.iter().map(|m| m.0).collect();
    assert_eq!(names, expect, "{name}: the WGSL members and the Rust fields differ");
    for ((m, wgsl), (_, r)) in members.iter().zip(rust) {
        assert_eq!(*wgsl, *r, "{name}.{m}: WGSL offset {wgsl}, Rust offset {r}");
    }
    assert_eq!(size, rust_size, "{name}: WGSL size {size}, Rust size {rust_size}");
}

#[test]
fn textured_uniforms_match_the_shader() {
    check(
        &textured_source(),
        "Light",
        size_of::<LightUniform>(),
        &[("vector", offset_of!(LightUniform, vector)), ("radiance", offset_of!(LightUniform, radiance))],
    );
    check(
        &textured_source(),
        "Frame",
        size_of::<FrameUniform>(),
        &[
            ("view_proj", offset_of!(FrameUniform, view_proj)),
            ("camera", offset_of!(FrameUniform, camera)),
            ("ambient", offset_of!(FrameUniform, ambient)),
            ("background", offset_of!(FrameUniform, background)),
            ("params", offset_of!(FrameUniform, params)),
            ("lights", offset_of!(FrameUniform, lights)),
        ],
    );
    check(
        &textured_source(),
        "Material",
        size_of::<MaterialUniform>(),
        &[
            ("base_color", offset_of!(MaterialUniform, base_color)),
            ("uv_scale", offset_of!(MaterialUniform, uv_scale)),
            ("specular", offset_of!(MaterialUniform, specular)),
            ("shininess", offset_of!(MaterialUniform, shininess)),
            ("has_texture", offset_of!(MaterialUniform, has_texture)),
            ("filter_mode", offset_of!(MaterialUniform, filter)),
            ("wrap", offset_of!(MaterialUniform, wrap)),
            ("level_rule", offset_of!(MaterialUniform, level_rule)),
            ("lod_bias", offset_of!(MaterialUniform, lod_bias)),
            ("level_count", offset_of!(MaterialUniform, level_count)),
            ("size", offset_of!(MaterialUniform, size)),
            ("atlas_size", offset_of!(MaterialUniform, atlas_size)),
            ("one_sided", offset_of!(MaterialUniform, one_sided)),
            ("_pad", offset_of!(MaterialUniform, _pad)),
            ("origins", offset_of!(MaterialUniform, origins)),
        ],
    );
}

#[test]
fn nurbs_uniform_matches_the_shader() {
    check(
        &nurbs_source(),
        "Frame",
        size_of::<NurbsFrame>(),
        &[
            ("view_proj", offset_of!(NurbsFrame, view_proj)),
            ("camera", offset_of!(NurbsFrame, camera)),
            ("light", offset_of!(NurbsFrame, light)),
            ("params", offset_of!(NurbsFrame, params)),
            ("ranges", offset_of!(NurbsFrame, ranges)),
            ("background", offset_of!(NurbsFrame, background)),
            ("model", offset_of!(NurbsFrame, model)),
            ("pull", offset_of!(NurbsFrame, pull)),
            ("lines", offset_of!(NurbsFrame, lines)),
            ("up", offset_of!(NurbsFrame, up)),
        ],
    );
}

#[test]
fn btf_uniform_matches_the_shader_in_every_layout() {
    for layout in Layout::ALL {
        check(
            &layout_source(layout),
            "Frame",
            size_of::<BtfFrame>(),
            &[
                ("view_proj", offset_of!(BtfFrame, view_proj)),
                ("camera", offset_of!(BtfFrame, camera)),
                ("light", offset_of!(BtfFrame, light)),
                ("background", offset_of!(BtfFrame, background)),
                ("tex_size", offset_of!(BtfFrame, tex_size)),
                ("sizes", offset_of!(BtfFrame, sizes)),
                ("tile", offset_of!(BtfFrame, tile)),
                ("strides", offset_of!(BtfFrame, strides)),
                ("theta", offset_of!(BtfFrame, theta)),
                ("mip", offset_of!(BtfFrame, mip)),
            ],
        );
    }
}

#[test]
fn flight_uniform_matches_the_shader() {
    check(
        &terrain_source(),
        "Fly",
        size_of::<FlyUniform>(),
        &[
            ("view_proj", offset_of!(FlyUniform, view_proj)),
            ("eye", offset_of!(FlyUniform, eye)),
            ("fwd", offset_of!(FlyUniform, fwd)),
            ("right", offset_of!(FlyUniform, right)),
            ("up", offset_of!(FlyUniform, up)),
            ("sizes", offset_of!(FlyUniform, sizes)),
            ("params", offset_of!(FlyUniform, params)),
        ],
    );
}

#[test]
fn a_mismatch_is_caught() {
    // the check itself: a WGSL struct one member short, and one padded differently
    let src = "struct S { a: vec4<f32>, b: vec2<f32>, c: f32 }";
    let r = std::panic::catch_unwind(|| check(src, "S", 32, &[("a", 0), ("b", 16)]));
    assert!(r.is_err(), "a missing member passes");
    let r = std::panic::catch_unwind(|| check(src, "S", 32, &[("a", 0), ("b", 16), ("c", 28)]));
    assert!(r.is_err(), "a wrong offset passes");
    check(src, "S", 32, &[("a", 0), ("b", 16), ("c", 24)]);
}

#[test]
fn shared_helpers_live_in_one_file() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    for f in ["textured.wgsl", "btf.wgsl", "nurbs.wgsl", "terrain.wgsl"] {
        let s = std::fs::read_to_string(dir.join(f)).unwrap();
        assert!(!s.contains("fn linear_to_srgb"), "{f} defines linear_to_srgb again; it lives in common.wgsl");
    }
    let common = std::fs::read_to_string(dir.join("common.wgsl")).unwrap();
    assert!(common.contains("fn linear_to_srgb"));
    // every composed source has it once, and parses
    for (name, src) in [
        ("textured", textured_source()),
        ("nurbs", nurbs_source()),
        ("terrain", terrain_source()),
        ("btf (f)", layout_source(Layout::F)),
    ] {
        assert_eq!(src.matches("fn linear_to_srgb").count(), 1, "{name}");
        naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
    }
}

#[test]
fn nurbs_modes_are_named_alike_in_both_programs() {
    use hitex_render::nurbs::NurbsMode;
    let src = nurbs_source();
    let module = naga::front::wgsl::parse_str(&src).unwrap();
    for (name, mode) in NurbsMode::ALL {
        let constant = format!("MODE_{}", name.to_ascii_uppercase().replace('-', "_"));
        let c = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(constant.as_str()))
            .unwrap_or_else(|| panic!("{constant} missing"))
            .1;
        match module.global_expressions[c.init] {
            naga::Expression::Literal(naga::Literal::U32(v)) => assert_eq!(v, mode.index(), "{constant}"),
            ref e => panic!("{constant} = {e:?}"),
        }
        // the shader compares the mode by name only
        let raw = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/nurbs.wgsl"))
            .unwrap();
        for k in 0..=9 {
            assert!(!raw.contains(&format!("mode == {k}u")), "nurbs.wgsl compares the mode with {k}u");
        }
    }
}

/// Every shader as compiled: (name, source), the BTF one per layout.
fn composed_sources() -> Vec<(String, String)> {
    let mut sources = vec![
        ("textured".to_string(), textured_source()),
        ("nurbs".to_string(), nurbs_source()),
        ("terrain".to_string(), terrain_source()),
    ];
    for layout in Layout::ALL {
        sources.push((format!("btf {layout:?}"), layout_source(layout)));
    }
    sources
}

/// Every composed shader passes naga's validator (types, builtins, uniformity), so a
/// shader error shows here with its line rather than as an invalid pipeline at draw time.
#[test]
fn every_composed_shader_validates() {
    for (name, src) in composed_sources() {
        let module =
            naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
    }
}

/// The codes of filter, wrap, level rule, display mode, tone map and flight
/// sampler: every composed shader holds each as the constant the Rust table
/// gives, and compares them by name only.
#[test]
fn codes_are_named_alike_in_both_programs() {
    use hitex_render::codes::table;
    for (name, src) in &composed_sources() {
        let module = naga::front::wgsl::parse_str(src).unwrap();
        for (choice, value, code) in table() {
            let constant = format!("{choice}_{}", value.to_ascii_uppercase().replace('-', "_"));
            let c = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(constant.as_str()))
                .unwrap_or_else(|| panic!("{name}: {constant} missing"))
                .1;
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => assert_eq!(v, code, "{name}: {constant}"),
                ref e => panic!("{name}: {constant} = {e:?}"),
            }
        }
    }
    // codes compared as numbers: none left in the shaders
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    for (f, words) in [
        ("textured.wgsl", &["wrap ==", "rule ==", "filter_mode ==", "mode =="][..]),
        ("btf.wgsl", &["mode =="][..]),
        ("terrain.wgsl", &["sampler ==", "SAMPLER ==", "SAMPLER !="][..]),
    ] {
        let s = std::fs::read_to_string(dir.join(f)).unwrap();
        for w in words {
            for k in 0..=9 {
                assert!(!s.contains(&format!("{w} {k}u")), "{f} compares `{w} {k}u`");
            }
        }
    }
}
