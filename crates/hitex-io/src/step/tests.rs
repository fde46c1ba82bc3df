use super::*;
use hitex_core::nurbs::continuity::{CheckOptions, Face, check};

/// A STEP file around `data` (one instance per line).
pub(crate) fn step_file(data: &str) -> String {
    format!(
        "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('t','',(''),(''),'','','');\n\
         FILE_SCHEMA(('AUTOMOTIVE_DESIGN'));\nENDSEC;\nDATA;\n{data}ENDSEC;\nEND-ISO-10303-21;\n"
    )
}

/// Placement, unit context and a 40 × 30 plate face with a hole of radius 5
/// at (10, 5): the plate's plane, outer square of four lines, the hole a full
/// circle through one vertex.
const PLATE: &str = "\
#1=CARTESIAN_POINT('',(0.,0.,0.));
#2=DIRECTION('',(0.,0.,1.));
#3=DIRECTION('',(1.,0.,0.));
#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);
#5=PLANE('',#4);
#10=CARTESIAN_POINT('',(-20.,-15.,0.));
#11=CARTESIAN_POINT('',(20.,-15.,0.));
#12=CARTESIAN_POINT('',(20.,15.,0.));
#13=CARTESIAN_POINT('',(-20.,15.,0.));
#14=VERTEX_POINT('',#10);
#15=VERTEX_POINT('',#11);
#16=VERTEX_POINT('',#12);
#17=VERTEX_POINT('',#13);
#20=VECTOR('',#3,1.);
#21=DIRECTION('',(0.,1.,0.));
#22=VECTOR('',#21,1.);
#23=LINE('',#10,#20);
#24=LINE('',#11,#22);
#25=LINE('',#13,#20);
#26=LINE('',#10,#22);
#30=EDGE_CURVE('',#14,#15,#23,.T.);
#31=EDGE_CURVE('',#15,#16,#24,.T.);
#32=EDGE_CURVE('',#17,#16,#25,.T.);
#33=EDGE_CURVE('',#14,#17,#26,.T.);
#34=ORIENTED_EDGE('',*,*,#30,.T.);
#35=ORIENTED_EDGE('',*,*,#31,.T.);
#36=ORIENTED_EDGE('',*,*,#32,.F.);
#37=ORIENTED_EDGE('',*,*,#33,.F.);
#38=EDGE_LOOP('',(#34,#35,#36,#37));
#39=FACE_OUTER_BOUND('',#38,.T.);
#40=CARTESIAN_POINT('',(10.,5.,0.));
#41=AXIS2_PLACEMENT_3D('',#40,#2,#3);
#42=CIRCLE('',#41,5.);
#43=CARTESIAN_POINT('',(15.,5.,0.));
#44=VERTEX_POINT('',#43);
#45=EDGE_CURVE('',#44,#44,#42,.T.);
#46=ORIENTED_EDGE('',*,*,#45,.F.);
#47=EDGE_LOOP('',(#46));
#48=FACE_BOUND('',#47,.T.);
#49=ADVANCED_FACE('',(#39,#48),#5,.T.);
";

/// Whether `p` is inside an odd number of loops (the renderer's rule).
fn inside(loops: &[Vec<[f64; 2]>], p: [f64; 2]) -> bool {
    hitex_core::nurbs::measure::inside_loops(loops, p)
}

fn read(data: &str) -> StepModel {
    parse_step(step_file(data).as_bytes(), "t.stp", &StepOptions { chord_tolerance: Some(1e-3) }).unwrap()
}

#[test]
fn a_plate_with_a_hole_keeps_the_plate_and_cuts_the_hole() {
    let m = read(&format!("{PLATE}#50=CLOSED_SHELL('',(#49));\n"));
    assert_eq!(m.surfaces.len(), 1, "{:?}", m.warnings);
    let p = &m.surfaces[0];
    assert_eq!(p.directory_entry, 49);
    assert_eq!(p.trim.len(), 2);
    // the plane's parameters are its x, y
    for (q, want) in [
        ([0.0, 0.0], true),
        ([10.0, 5.0], false),
        ([14.5, 5.0], false),
        ([15.5, 5.0], true),
        ([19.9, -14.9], true),
        ([20.5, 0.0], false),
    ] {
        assert_eq!(inside(&p.trim, q), want, "{q:?}");
        if want {
            let s = p.surface.point(q[0], q[1]);
            assert!((s[0] - q[0]).abs() < 1e-12 && (s[1] - q[1]).abs() < 1e-12 && s[2].abs() < 1e-12);
        }
    }
    // the hole's polygon lies within the chord tolerance of the circle, vertices on it
    let hole = p.trim.iter().find(|l| l.len() > 5).unwrap();
    for w in hole.windows(2) {
        let r = |q: [f64; 2]| ((q[0] - 10.0).powi(2) + (q[1] - 5.0).powi(2)).sqrt();
        assert!((r(w[0]) - 5.0).abs() < 1e-12);
        let mid = [0.5 * (w[0][0] + w[1][0]), 0.5 * (w[0][1] + w[1][1])];
        assert!(5.0 - r(mid) <= 1e-3 + 1e-12, "sag {}", 5.0 - r(mid));
    }
    // adaptive, not a fixed count: a coarser tolerance takes fewer points
    let coarse = parse_step(step_file(PLATE).as_bytes(), "t", &StepOptions { chord_tolerance: Some(0.1) }).unwrap();
    let n = coarse.surfaces[0].trim.iter().map(|l| l.len()).max().unwrap();
    assert!(n < hole.len() / 3, "{n} vs {}", hole.len());
}

/// A cylinder of radius 2 about z from z = 0 to z = 3, bounded by its two
/// circles (no seam edge), as CAD systems write a through hole or a boss.
const CYLINDER: &str = "\
#1=CARTESIAN_POINT('',(0.,0.,0.));
#2=DIRECTION('',(0.,0.,1.));
#3=DIRECTION('',(1.,0.,0.));
#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);
#5=CYLINDRICAL_SURFACE('',#4,2.);
#6=CARTESIAN_POINT('',(0.,0.,3.));
#7=AXIS2_PLACEMENT_3D('',#6,#2,#3);
#8=CIRCLE('',#4,2.);
#9=CIRCLE('',#7,2.);
#10=CARTESIAN_POINT('',(0.,2.,0.));
#11=CARTESIAN_POINT('',(0.,2.,3.));
#12=VERTEX_POINT('',#10);
#13=VERTEX_POINT('',#11);
#14=EDGE_CURVE('',#12,#12,#8,.T.);
#15=EDGE_CURVE('',#13,#13,#9,.T.);
#16=ORIENTED_EDGE('',*,*,#14,.T.);
#17=ORIENTED_EDGE('',*,*,#15,.F.);
#18=EDGE_LOOP('',(#16));
#19=EDGE_LOOP('',(#17));
#20=FACE_BOUND('',#18,.T.);
#21=FACE_BOUND('',#19,.T.);
#22=ADVANCED_FACE('',(#20,#21),#5,.T.);
#23=CLOSED_SHELL('',(#22));
";

#[test]
fn a_cylinder_between_two_circles_is_whole_and_exact() {
    let m = read(CYLINDER);
    assert_eq!(m.surfaces.len(), 1, "{:?}", m.warnings);
    let p = &m.surfaces[0];
    let ((u0, u1), (v0, v1)) = p.range;
    assert!((u1 - u0 - std::f64::consts::TAU).abs() < 1e-9, "a full turn: {u0}..{u1}");
    assert_eq!(p.surface.degree_u, 2, "circles are rational quadratics");
    let mut kept = 0;
    for i in 0..=40 {
        for j in 1..40 {
            let (u, v) = (u0 + (u1 - u0) * i as f64 / 40.0, v0 + (v1 - v0) * j as f64 / 40.0);
            let s = p.surface.point(u, v);
            assert!(((s[0] * s[0] + s[1] * s[1]).sqrt() - 2.0).abs() < 1e-12, "off the cylinder at {u},{v}");
            let want = s[2] > 1e-6 && s[2] < 3.0 - 1e-6;
            if want && i > 0 && i < 40 {
                assert!(inside(&p.trim, [u, v]), "z = {} at u = {u} must be kept", s[2]);
                kept += 1;
            }
            if s[2] < -1e-6 || s[2] > 3.0 + 1e-6 {
                assert!(!inside(&p.trim, [u, v]), "z = {} is off the face", s[2]);
            }
        }
    }
    assert!(kept > 1000);
    // the outward normal: the face agrees with the surface
    let n = p.surface.normal(0.5 * (u0 + u1), 0.5 * (v0 + v1));
    let s = p.surface.point(0.5 * (u0 + u1), 0.5 * (v0 + v1));
    assert!(n[0] * s[0] + n[1] * s[1] > 0.0);
}

#[test]
fn a_reversed_face_turns_its_normal() {
    let m = read(&CYLINDER.replace("#5,.T.);", "#5,.F.);"));
    let p = &m.surfaces[0];
    let ((u0, u1), (v0, v1)) = p.range;
    let (u, v) = (0.3 * u0 + 0.7 * u1, 0.5 * (v0 + v1));
    let (n, s) = (p.surface.normal(u, v), p.surface.point(u, v));
    assert!(n[0] * s[0] + n[1] * s[1] < 0.0, "inward, as the face says");
    assert!(inside(&p.trim, [u, v]));
}

#[test]
fn an_assembly_places_each_instance() {
    // the plate's shape representation placed twice in an assembly, once moved by (100, 0, 0)
    let data = format!(
        "{PLATE}#50=MANIFOLD_SOLID_BREP('',#51);\n#51=CLOSED_SHELL('',(#49));\n\
         #60=ADVANCED_BREP_SHAPE_REPRESENTATION('',(#4,#50),#99);\n\
         #61=SHAPE_REPRESENTATION('',(#4,#62,#63),#99);\n\
         #62=AXIS2_PLACEMENT_3D('',#1,#2,#3);\n#64=CARTESIAN_POINT('',(100.,0.,0.));\n\
         #63=AXIS2_PLACEMENT_3D('',#64,#21,#3);\n\
         #70=(REPRESENTATION_RELATIONSHIP('','',#60,#61) REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION(#71) SHAPE_REPRESENTATION_RELATIONSHIP());\n\
         #71=ITEM_DEFINED_TRANSFORMATION('','',#4,#62);\n\
         #72=(REPRESENTATION_RELATIONSHIP('','',#60,#61) REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION(#73) SHAPE_REPRESENTATION_RELATIONSHIP());\n\
         #73=ITEM_DEFINED_TRANSFORMATION('','',#4,#63);\n\
         #99=GEOMETRIC_REPRESENTATION_CONTEXT(3);\n"
    );
    let m = read(&data);
    assert_eq!(m.surfaces.len(), 2, "{:?}", m.warnings);
    let centre = |k: usize| m.surfaces[k].surface.point(0.0, 0.0);
    let (a, b) = (centre(0), centre(1));
    assert!(a.iter().map(|x| x.abs()).sum::<f64>() < 1e-9, "{a:?}");
    // the second placement moves to x = 100 and turns z onto y: the plate stands up
    assert!((b[0] - 100.0).abs() < 1e-9 && b[1].abs() < 1e-9 && b[2].abs() < 1e-9, "{b:?}");
    let n = m.surfaces[1].surface.normal(0.0, 0.0);
    assert!((n[1].abs() - 1.0).abs() < 1e-9, "{n:?}");
}

#[test]
fn faces_that_cannot_be_read_are_named_and_the_rest_kept() {
    let data = format!(
        "{PLATE}#60=SURFACE_OF_LINEAR_EXTRUSION('',#23,#20);\n#61=ADVANCED_FACE('',(#39),#60,.T.);\n\
         #62=ADVANCED_FACE('',(#39),#999,.T.);\n#63=CLOSED_SHELL('',(#49,#61,#62));\n"
    );
    let m = read(&data);
    assert_eq!(m.surfaces.len(), 1);
    let w = m.warnings.join("\n");
    assert!(w.contains("#61") && w.contains("a line extruded along itself"), "{w}");
    assert!(w.contains("#62") && w.contains("#999"), "{w}");
}

#[test]
fn broken_files_are_clear_errors() {
    let cases: Vec<(String, &str)> = vec![
        (step_file("#1=CARTESIAN_POINT('',(0.,0.,0.));\n#2=DIRECTION('',(0.,0.,1.));\n"), "no B-rep faces"),
        (
            step_file(
                &PLATE.replace("#10=CARTESIAN_POINT('',(-20.,-15.,0.));", "#10=CARTESIAN_POINT('',(-20.,-15.,0.);"),
            ),
            "line 13: #10: expected",
        ),
        (step_file(&PLATE.replace("#5=PLANE('',#4);", "#5=PLANE('',#8);")), "no face could be read"),
        (step_file(&CYLINDER.replace("2.);\n#6", "-2.);\n#6")), "radius -2 is not positive"),
        (step_file(PLATE)[..400].to_string(), "truncated"),
    ];
    for (text, want) in cases {
        let e = parse_step(text.as_bytes(), "bad.stp", &StepOptions::default()).unwrap_err().to_string();
        assert!(e.starts_with("bad.stp: ") && e.contains(want), "{want}: {e}");
    }
    let e = parse_step(step_file(PLATE).as_bytes(), "t", &StepOptions { chord_tolerance: Some(0.0) }).unwrap_err();
    assert!(e.message.contains("chord tolerance"), "{e}");
}

fn data_file(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cad").join(name)
}

/// Every edge of a closed solid is shared by two faces: the faces as read
/// must meet along all their trims, with no naked edge, to the tolerance.
fn closed_and_watertight(m: &StepModel, gap: f64) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for s in &m.surfaces {
        let (a, b) = s.surface.bounds();
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    let size = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let faces: Vec<Face> =
        m.surfaces.iter().map(|s| Face { surface: &s.surface, range: s.range, loops: &s.trim }).collect();
    let opts = CheckOptions { spacing: size / 400.0, match_radius: (2.0 * gap).max(2e-3 * size) };
    let edges = check(&faces, &opts, size);
    let naked: Vec<_> = edges.iter().filter(|e| e.neighbour.is_none()).map(|e| (e.face, e.samples, e.length)).collect();
    assert!(naked.is_empty(), "naked edges (face, samples, length): {naked:?}");
    let worst = edges.iter().map(|e| e.g0.value).fold(0.0, f64::max);
    assert!(worst <= gap, "largest gap {worst} > {gap}");
}

#[test]
fn the_machined_part_reads_whole_and_closed() {
    let m = load_step(&data_file("face_recognition_sample_part.stp"), &StepOptions::default()).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    assert_eq!(m.surfaces.len(), 23);
    assert_eq!(m.surface_types.get("PLANE"), Some(&17));
    assert_eq!(m.surface_types.get("CYLINDRICAL_SURFACE"), Some(&6));
    assert_eq!(m.length_unit, "mm");
    closed_and_watertight(&m, 2.0 * m.chord_tolerance);
}

#[test]
fn the_assembly_places_its_parts() {
    let m = load_step(&data_file("as1-oc-214.stp"), &StepOptions::default()).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    // 5 solids (plate, L-bracket, rod, nut, bolt) placed 9 times over 3 levels
    assert!(m.instances >= 9, "{}", m.instances);
    assert_eq!(m.surfaces.len(), 160);
    // parts that share a shape sit apart: no two patches of one face coincide
    let mut seen = std::collections::HashMap::new();
    for s in &m.surfaces {
        let c = s.surface.point(0.5 * (s.range.0.0 + s.range.0.1), 0.5 * (s.range.1.0 + s.range.1.1));
        let key =
            (s.directory_entry, (c[0] * 1e3).round() as i64, (c[1] * 1e3).round() as i64, (c[2] * 1e3).round() as i64);
        assert!(seen.insert(key, ()).is_none(), "face #{} placed twice at {c:?}", s.directory_entry);
    }
    // colours from the styles of the solids: 4 named or RGB colours over 18 instances
    assert_eq!(m.colors.len(), m.surfaces.len());
    assert!(m.colors.iter().all(Option::is_some));
    let distinct: std::collections::HashSet<[u32; 3]> =
        m.colors.iter().flatten().map(|c| c.map(f32::to_bits)).collect();
    assert_eq!(distinct.len(), 5, "{distinct:?}");
    let s = |x: f32| hitex_core::texture::srgb_to_linear(x);
    assert!(m.colors.iter().flatten().any(|c| *c == [s(0.8), s(1.0), s(0.0)]));
    assert!(m.colors.iter().flatten().any(|c| *c == [0.0, 0.0, 1.0]));
    // every part is a closed solid, its B-spline faces trimmed through their pcurves
    closed_and_watertight(&m, 2.0 * m.chord_tolerance);
}

#[test]
fn the_spline_cage_reads_its_pcurves() {
    let m = load_step(&data_file("splinecage.stp"), &StepOptions::default()).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    assert_eq!(m.surfaces.len(), 4);
    // each trim point lies in its surface's domain, and the trims close
    for s in &m.surfaces {
        let ((u0, u1), (v0, v1)) = s.surface.domain();
        for l in &s.trim {
            assert_eq!(l.first(), l.last());
            for p in l {
                assert!(p[0] >= u0 - 1e-9 && p[0] <= u1 + 1e-9 && p[1] >= v0 - 1e-9 && p[1] <= v1 + 1e-9, "{p:?}");
            }
        }
    }
}

fn kept_area(m: &StepModel) -> f64 {
    m.surfaces.iter().map(|s| hitex_core::nurbs::measure::trimmed_measure(&s.surface, s.range, &s.trim).area).sum()
}

#[test]
fn swept_surfaces_convert_exactly_and_trim_like_the_cylinder() {
    // the cylinder of radius 2 as an extruded circle and as a revolved line
    let extruded = CYLINDER.replace(
        "#5=CYLINDRICAL_SURFACE('',#4,2.);",
        "#5=SURFACE_OF_LINEAR_EXTRUSION('',#8,#30);\n#30=VECTOR('',#2,1.);",
    );
    let revolved = CYLINDER.replace(
        "#5=CYLINDRICAL_SURFACE('',#4,2.);",
        "#5=SURFACE_OF_REVOLUTION('',#31,#33);\n#30=CARTESIAN_POINT('',(2.,0.,0.));\n#31=LINE('',#30,#32);\n\
         #32=VECTOR('',#2,1.);\n#33=AXIS1_PLACEMENT('',#1,#2);",
    );
    for (name, text) in [("extrusion", extruded), ("revolution", revolved)] {
        let m = read(&text);
        assert_eq!(m.surfaces.len(), 1, "{name}: {:?}", m.warnings);
        assert_eq!(m.census.get(name), Some(&1));
        let p = &m.surfaces[0];
        let ((u0, u1), (v0, v1)) = p.range;
        for i in 0..=16 {
            for j in 0..=16 {
                let (u, v) = (u0 + (u1 - u0) * i as f64 / 16.0, v0 + (v1 - v0) * j as f64 / 16.0);
                let s = p.surface.point(u, v);
                assert!(((s[0] * s[0] + s[1] * s[1]).sqrt() - 2.0).abs() < 1e-12, "{name}: off the cylinder");
            }
        }
        // the side between the circles, exactly: 2π·2·3
        let a = kept_area(&m);
        let want = std::f64::consts::TAU * 2.0 * 3.0;
        assert!((a - want).abs() / want < 1e-3, "{name}: area {a} vs {want}");
    }
}

#[test]
fn trimmed_areas_match_their_formulas() {
    // plate 40 × 30 less a hole of radius 5 (the chord tolerance 1e-3 shrinks the hole by < 1e-3)
    let m = read(PLATE);
    let want = 1200.0 - std::f64::consts::PI * 25.0;
    assert!((kept_area(&m) - want).abs() < 0.04, "{} vs {want}", kept_area(&m));
    // the cylinder's side
    let want = std::f64::consts::TAU * 6.0;
    assert!((kept_area(&read(CYLINDER)) - want).abs() / want < 1e-3);
    // a spherical cap of radius 3 above z = 1.5 (bounded by one circle, closed at the pole): 2πRh
    let cap = "\
#1=CARTESIAN_POINT('',(0.,0.,0.));
#2=DIRECTION('',(0.,0.,1.));
#3=DIRECTION('',(1.,0.,0.));
#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);
#5=SPHERICAL_SURFACE('',#4,3.);
#6=CARTESIAN_POINT('',(0.,0.,1.5));
#7=AXIS2_PLACEMENT_3D('',#6,#2,#3);
#8=CIRCLE('',#7,2.598076211353316);
#10=CARTESIAN_POINT('',(2.598076211353316,0.,1.5));
#12=VERTEX_POINT('',#10);
#14=EDGE_CURVE('',#12,#12,#8,.T.);
#16=ORIENTED_EDGE('',*,*,#14,.T.);
#18=EDGE_LOOP('',(#16));
#20=FACE_OUTER_BOUND('',#18,.T.);
#22=ADVANCED_FACE('',(#20),#5,.T.);
#23=OPEN_SHELL('',(#22));
";
    let m = read(cap);
    assert_eq!(m.census.get("sphere"), Some(&1));
    let want = std::f64::consts::TAU * 3.0 * 1.5;
    let a = kept_area(&m);
    assert!((a - want).abs() / want < 1e-3, "cap {a} vs {want}");
    // the other way round the loop keeps the rest of the sphere: 2πR(R + 1.5)
    let m = read(&cap.replace("#14,.T.);\n#18", "#14,.F.);\n#18"));
    let want = std::f64::consts::TAU * 3.0 * 4.5;
    let a = kept_area(&m);
    assert!((a - want).abs() / want < 1e-3, "rest {a} vs {want}");
}

#[test]
fn offset_surfaces_are_refused_by_name() {
    let m = read(&format!(
        "{PLATE}#60=OFFSET_SURFACE('',#5,2.5,.F.);\n#61=ADVANCED_FACE('',(#39),#60,.T.);\n#63=CLOSED_SHELL('',(#49,#61));\n"
    ));
    assert_eq!(m.surfaces.len(), 1);
    assert_eq!(m.census.get("offset"), Some(&1));
    let w = m.warnings.join("\n");
    assert!(w.contains("#61") && w.contains("OFFSET_SURFACE (distance 2.5 from #5)"), "{w}");
}

#[test]
fn hostile_structures_are_refused_or_skipped_quickly() {
    // an empty polygon loop, limits of 10^15 turns, a placement cycle through mapped items
    let data = format!(
        "{PLATE}#60=POLY_LOOP('',());\n#61=FACE_BOUND('',#60,.T.);\n#62=ADVANCED_FACE('',(#39,#61),#5,.T.);\n\
         #70=CYLINDRICAL_SURFACE('',#4,2.);\n#71=RECTANGULAR_TRIMMED_SURFACE('',#70,0.,1.E15,0.,1.,.T.,.T.);\n\
         #72=ADVANCED_FACE('',(),#71,.T.);\n#73=CLOSED_SHELL('',(#49,#62,#72));\n\
         #80=SHAPE_REPRESENTATION('',(#81,#82,#73),#99);\n#81=MAPPED_ITEM('',#83,#4);\n#82=MAPPED_ITEM('',#83,#4);\n\
         #83=REPRESENTATION_MAP(#4,#80);\n#99=GEOMETRIC_REPRESENTATION_CONTEXT(3);\n"
    );
    let t = std::time::Instant::now();
    let m = read(&data);
    assert!(t.elapsed().as_secs() < 20, "took {:?}", t.elapsed());
    let w = m.warnings.join("\n");
    assert!(w.contains("#62") && w.contains("POLY_LOOP #60 has no points"), "{w}");
    assert!(w.contains("#72") && w.contains("more than a turn"), "{w}");
    assert!(m.surfaces.iter().all(|s| s.directory_entry == 49) && !m.surfaces.is_empty());
    // directions of huge ratios normalise instead of overflowing
    let m = read(&PLATE.replace("#2=DIRECTION('',(0.,0.,1.));", "#2=DIRECTION('',(0.,0.,1.E300));"));
    let n = m.surfaces[0].surface.normal(0.0, 0.0);
    assert!((n[2].abs() - 1.0).abs() < 1e-12, "{n:?}");
}

#[test]
fn every_export_reads_the_trims_back_point_for_point() {
    // the machined part's loops met a seam or an edge end twice in a row:
    // IGES and OBJ dropped the repeat on reading, so their loops came back
    // one point short of the model's
    for name in ["face_recognition_sample_part.stp", "as1-oc-214.stp", "splinecage.stp"] {
        let m = load_step(&data_file(name), &StepOptions::default()).unwrap();
        for l in m.surfaces.iter().flat_map(|s| &s.trim) {
            assert!(l.windows(2).all(|w| w[0] != w[1]), "{name}: a vertex repeated in a loop");
        }
        let iges = crate::iges::parse_iges(&crate::nurbs_json::to_iges(&m.surfaces, "t"), "t").unwrap();
        let obj = crate::obj_freeform::parse_obj_freeform(&crate::obj_freeform::to_obj_freeform(&m.surfaces)).unwrap();
        for (what, back) in [("IGES", &iges.surfaces), ("OBJ", &obj)] {
            assert_eq!(back.len(), m.surfaces.len(), "{name} {what}");
            for (a, b) in m.surfaces.iter().zip(back.iter()) {
                assert_eq!(a.trim, b.trim, "{name} {what}: face #{}", a.directory_entry);
            }
        }
    }
}
