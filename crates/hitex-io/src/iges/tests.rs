use super::*;

fn line(data: &str, section: char, seq: usize) -> String {
    format!("{data:<72}{section}{seq:>7}\n")
}

/// A minimal, well-formed file with one bilinear patch.
fn tiny(record: &str) -> String {
    let mut s = line("tiny test", 'S', 1);
    s += &line("1H,,1H;;", 'G', 1);
    s += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}", 128, 1, 0, 1, 0, 0, 0, 0, 0), 'D', 1);
    s += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}", 128, 0, 0, 1, 0), 'D', 2);
    let mut k = 1;
    for chunk in record.as_bytes().chunks(64) {
        let txt = std::str::from_utf8(chunk).unwrap();
        s += &format!("{txt:<64}{:>8}P{k:>7}\n", 1);
        k += 1;
    }
    s += &line(&format!("S{:>7}G{:>7}D{:>7}P{:>7}", 1, 1, 2, k - 1), 'T', 1);
    s
}

/// A well-formed file of several entities with consistent pointers.
pub(crate) fn iges_file(entities: &[(i64, &str)]) -> String {
    let with: Vec<(i64, &str, usize)> = entities.iter().map(|(t, r)| (*t, *r, 0)).collect();
    iges_file_placed(&with)
}

/// Like [`iges_file`], each entity with the directory pointer of its
/// transformation matrix (0: none).
pub(crate) fn iges_file_placed(entities: &[(i64, &str, usize)]) -> String {
    let with: Vec<(i64, &str, usize, i64)> = entities.iter().map(|&(t, r, m)| (t, r, m, 0)).collect();
    iges_file_coloured(&with)
}

/// Like [`iges_file_placed`], each entity with its colour number too
/// (directory field 13: 0 none, 1–8 standard, −pointer to a 314).
pub(crate) fn iges_file_coloured(entities: &[(i64, &str, usize, i64)]) -> String {
    let mut s = line("generated", 'S', 1);
    s += &line("1H,,1H;;", 'G', 1);
    let mut dir = String::new();
    let mut par = String::new();
    let mut pl = 1;
    for (k, (ty, rec, tr, colour)) in entities.iter().enumerate() {
        let lines: Vec<String> = rec.as_bytes().chunks(64).map(|c| String::from_utf8_lossy(c).to_string()).collect();
        let de = 2 * k + 1;
        dir += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}", ty, pl, 0, 1, 0, 0, tr, 0, 0), 'D', de);
        dir += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}", ty, 0, colour, lines.len(), 0), 'D', de + 1);
        for l in lines {
            par += &format!("{l:<64}{de:>8}P{pl:>7}\n");
            pl += 1;
        }
    }
    s += &dir;
    s += &par;
    s += &line(&format!("S{:>7}G{:>7}D{:>7}P{:>7}", 1, 1, 2 * entities.len(), pl - 1), 'T', 1);
    s
}

#[test]
fn a_file_without_surfaces_says_what_it_holds() {
    let text = iges_file(&[
        (110, "110,0.,0.,0.,1.,0.,0.;"),
        (110, "110,1.,0.,0.,1.,1.,0.;"),
        (116, "116,0.,0.,0.,0;"),
        (186, "186,0,1,0;"),
    ]);
    let e = parse_iges(&text, "part.igs").unwrap_err().to_string();
    assert_eq!(
        e,
        "part.igs: no surface found: it holds 2 × 110 (line), \
         1 × 116 (point), 1 × 186 (manifold solid B-rep); hitex reads rational B-spline (128), parametric \
         spline (114), revolved (120) and tabulated (122) surfaces, trimmed by 144/142"
    );
}

/// A unit square trimmed by a circular hole of radius 0.3 at its centre.
pub(crate) fn holed_square() -> String {
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let pts = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (1.0, 0.0),
    ];
    let mut circle = "126,8,2,0,0,0,0,0.,0.,0.,0.25,0.25,0.5,0.5,0.75,0.75,1.,1.,1.,".to_string();
    for i in 0..9 {
        circle += &format!("{},", if i % 2 == 1 { w } else { 1.0 });
    }
    for (x, y) in pts {
        circle += &format!("{},{},0.,", 0.5 + 0.3 * x, 0.5 + 0.3 * y);
    }
    circle += "0.,1.,0.,0.,1.;";
    iges_file(&[(128, BILINEAR), (126, &circle), (142, "142,0,1,3,0,1;"), (144, "144,1,0,1,0,5;")])
}

/// A unit square with two holes: a circle (entity 100) of radius 0.15
/// about (0.3, 0.5), and an ellipse (entity 104) of semi-axes 0.12 and
/// 0.25 placed about (0.7, 0.5) by a matrix (124).
pub(crate) fn arc_holes() -> String {
    iges_file_placed(&[
        (128, BILINEAR, 0),
        (100, "100,0.,0.3,0.5,0.45,0.5,0.45,0.5;", 0),
        (124, "124,1.,0.,0.,0.7,0.,1.,0.,0.5,0.,0.,1.,0.;", 0),
        (104, "104,0.0625,0.,0.0144,0.,0.,-0.0009,0.,0.12,0.,0.12,0.;", 5),
        (142, "142,0,1,3,0,1;", 0),
        (142, "142,0,1,7,0,1;", 0),
        (144, "144,1,0,2,0,9,11;", 0),
    ])
}

#[test]
fn arc_holes_fixture_is_current() {
    fixture_is_current("arc-holes.igs", &arc_holes());
    let m = parse_iges(&arc_holes(), "arc-holes.igs").unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let t = &m.surfaces[0].trim;
    assert_eq!(t.len(), 3);
    let pi = std::f64::consts::PI;
    assert!((area(&t[1]) / (pi * 0.0225) - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE);
    assert!((area(&t[2]) / (pi * 0.03) - 1.0).abs() < 4.0 * TRIM_CHORD_TOLERANCE);
}

#[test]
fn holed_square_fixture_is_current() {
    fixture_is_current("holed-square.igs", &holed_square());
}

/// `data/NAME`, a trimmed surface for tests and users, holds `text`
/// (`HITEX_BLESS=1` rewrites it).
fn fixture_is_current(name: &str, text: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(name);
    if std::env::var("HITEX_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, text).unwrap();
    }
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "{name}");
}

#[test]
fn transformation_matrices_place_surfaces() {
    // a quarter turn about z, then (10, 0, 0); a second matrix above it moves by (0, 0, 5)
    let turn = "124,0.,-1.,0.,10.,1.,0.,0.,0.,0.,0.,1.,0.;";
    let lift = "124,1.,0.,0.,0.,0.,1.,0.,0.,0.,0.,1.,5.;";
    let f = iges_file_placed(&[(124, lift, 0), (124, turn, 1), (128, BILINEAR, 3)]);
    let m = parse_iges(&f, "placed.igs").unwrap();
    assert_eq!(m.surfaces.len(), 1, "{:?}", m.warnings);
    let s = &m.surfaces[0].surface;
    // the bilinear patch's corner (1, 0, 0) → turned to (0, 1, 0) → (10, 1, 0) → lifted (10, 1, 5)
    let p = s.point(1.0, 0.0);
    assert!((p[0] - 10.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12 && (p[2] - 5.0).abs() < 1e-12, "{p:?}");
    assert!(!m.warnings.iter().any(|w| w.contains("124")), "{:?}", m.warnings);
    // a pointer to something other than a matrix is an error naming it
    let f = iges_file_placed(&[(110, "110,0.,0.,0.,1.,0.,0.;", 0), (128, BILINEAR, 1)]);
    let e = parse_iges(&f, "bad.igs").unwrap_err().to_string();
    assert!(e.contains("not a matrix (124)"), "{e}");
    // matrices pointing at each other
    let f = iges_file_placed(&[(124, lift, 3), (124, turn, 1), (128, BILINEAR, 3)]);
    let e = parse_iges(&f, "cycle.igs").unwrap_err().to_string();
    assert!(e.contains("cycle"), "{e}");
}

#[test]
fn trimmed_surface_gets_its_loops() {
    let m = parse_iges(&holed_square(), "holed.igs").unwrap();
    assert!(m.repairs.is_empty(), "{:?}", m.repairs);
    assert_eq!(m.surfaces.len(), 1, "the base surface is replaced by its trimmed form");
    let t = &m.surfaces[0].trim;
    assert_eq!(t.len(), 2);
    assert_eq!(t[0].len(), 5);
    // the hole: every sample on the circle of radius 0.3
    for p in &t[1] {
        let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)).sqrt();
        assert!((r - 0.3).abs() < 1e-12, "{p:?}");
    }
    // a 144 that points at nothing is a warning, and its surface stays untrimmed
    let bad = iges_file(&[(128, BILINEAR), (144, "144,1,1,0,77;")]);
    let m = parse_iges(&bad, "bad.igs").unwrap();
    assert!(m.surfaces[0].trim.is_empty());
    assert!(m.warnings.iter().any(|w| w.contains("entity 144")), "{:?}", m.warnings);
}

/// The unit bilinear patch with one hole bounded by `curves` (entries
/// 2 …, the last one the 142's parameter-space curve; each with its
/// matrix pointer): the hole's loop, or the file's warnings.
fn hole(curves: &[(i64, &str, usize)]) -> Result<Vec<[f64; 2]>, Vec<String>> {
    let last = 2 * curves.len() + 1;
    let c142 = format!("142,0,1,{last},0,1;");
    let c144 = format!("144,1,0,1,0,{};", last + 2);
    let mut all = vec![(128, BILINEAR, 0)];
    all.extend_from_slice(curves);
    all.push((142, &c142, 0));
    all.push((144, &c144, 0));
    let m = parse_iges(&iges_file_placed(&all), "hole.igs").unwrap();
    match m.surfaces[0].trim.get(1) {
        Some(l) => Ok(l.clone()),
        None => Err(m.warnings),
    }
}

fn area(l: &[[f64; 2]]) -> f64 {
    0.5 * l.windows(2).map(|w| w[0][0] * w[1][1] - w[1][0] * w[0][1]).sum::<f64>()
}

/// Largest distance of a chord's midpoint from the circle (c, r).
fn worst_sagitta(l: &[[f64; 2]], c: [f64; 2], r: f64) -> f64 {
    l.windows(2)
        .map(|w| r - (0.5 * (w[0][0] + w[1][0]) - c[0]).hypot(0.5 * (w[0][1] + w[1][1]) - c[1]))
        .fold(0.0, f64::max)
}

#[test]
fn circular_arcs_trim_to_the_chord_tolerance() {
    // a full circle (start = end), radius 0.3 about (0.5, 0.5)
    let l = hole(&[(100, "100,0.,0.5,0.5,0.8,0.5,0.8,0.5;", 0)]).unwrap();
    for p in &l {
        assert!(((p[0] - 0.5).hypot(p[1] - 0.5) - 0.3).abs() < 1e-12, "{p:?}");
    }
    let sag = worst_sagitta(&l, [0.5, 0.5], 0.3);
    assert!(sag <= TRIM_CHORD_TOLERANCE * 0.3 * 1.0001 && sag > 0.0, "{sag}");
    // counterclockwise, the circle's area to the chord tolerance, not thousands of points
    let a = area(&l);
    assert!((a / (std::f64::consts::PI * 0.09) - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE, "{a}");
    assert!(l.len() < 600, "{}", l.len());
    // a half circle of radius 1 closed by its diameter, as a composite
    // curve that a matrix scales by 1/4 and moves to (0.5, 0.5)
    let quarter = "124,0.25,0.,0.,0.5,0.,0.25,0.,0.5,0.,0.,1.,0.;";
    let l = hole(&[
        (124, quarter, 0),
        (100, "100,0.,0.,0.,1.,0.,-1.,0.;", 0),
        (110, "110,-1.,0.,0.,1.,0.,0.;", 0),
        (102, "102,2,5,7;", 3),
    ])
    .unwrap();
    assert!(l.iter().all(|p| p[1] >= 0.5 - 1e-12 && (p[0] - 0.5).hypot(p[1] - 0.5) <= 0.25 + 1e-12), "{l:?}");
    let half = std::f64::consts::PI * 0.0625 / 2.0;
    assert!((area(&l) / half - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE, "{}", area(&l));
    // a degenerate arc is a warning naming the entity; the surface stays
    let w = hole(&[(100, "100,0.,0.5,0.5,0.5,0.5,0.5,0.5;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("entity 100 (entry 2)") && w.contains("centre")), "{w:?}");
}

#[test]
fn conic_arcs_trim_on_their_curves() {
    // the ellipse x²/0.2² + y²/0.1² = 1, whole, moved to (0.5, 0.5)
    let shift = "124,1.,0.,0.,0.5,0.,1.,0.,0.5,0.,0.,1.,0.;";
    let l = hole(&[(124, shift, 0), (104, "104,25.,0.,100.,0.,0.,-1.,0.,0.2,0.,0.2,0.;", 3)]).unwrap();
    for p in &l {
        let (x, y) = (p[0] - 0.5, p[1] - 0.5);
        assert!((x * x / 0.04 + y * y / 0.01 - 1.0).abs() < 1e-12, "{p:?}");
    }
    let e = std::f64::consts::PI * 0.2 * 0.1;
    assert!((area(&l) / e - 1.0).abs() < 4.0 * TRIM_CHORD_TOLERANCE, "{}", area(&l));
    // the parabola y = 2x² from x = −0.5 to 0.5, closed by the line y = 0.5: area 1/3
    let l = hole(&[
        (104, "104,2.,0.,0.,0.,-1.,0.,0.,-0.5,0.5,0.5,0.5;", 0),
        (110, "110,0.5,0.5,0.,-0.5,0.5,0.;", 0),
        (102, "102,2,3,5;", 0),
    ])
    .unwrap();
    assert!(l.iter().all(|p| (p[1] - 2.0 * p[0] * p[0]).abs() < 1e-12 || (p[1] - 0.5).abs() < 1e-12), "{l:?}");
    assert!(l.len() > 10, "sampled, not a chord: {l:?}");
    assert!((area(&l).abs() - 1.0 / 3.0).abs() < 1e-4, "{}", area(&l));
    // the hyperbola x² − y² = 1: its left branch from (−cosh 1, sinh 1) to (−cosh 1, −sinh 1)
    let (c, s) = (1f64.cosh(), 1f64.sinh());
    let rec = format!("104,1.,0.,-1.,0.,0.,-1.,0.,{},{s},{},{};", -c, -c, -s);
    let l = hole(&[(104, &rec, 0)]).unwrap();
    for p in &l {
        assert!(p[0] < 0.0 && (p[0] * p[0] - p[1] * p[1] - 1.0).abs() < 1e-9, "{p:?}");
    }
    assert!(l.len() > 10);
    // off standard position: a warning naming the entity and why
    let w = hole(&[(104, "104,1.,0.5,1.,0.,0.,-1.,0.,1.,0.,1.,0.;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("entity 104 (entry 2)") && w.contains("standard position")), "{w:?}");
    let w = hole(&[(104, "104,1.,0.,1.,0.,0.,1.,0.,1.,0.,1.,0.;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("imaginary")), "{w:?}");
}

#[test]
fn copious_data_trims_as_its_points() {
    let l = hole(&[(106, "106,1,4,0.,0.1,0.1,0.9,0.1,0.9,0.9,0.1,0.9;", 0)]).unwrap();
    assert_eq!(l, vec![[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9], [0.1, 0.1]]);
    let l = hole(&[(106, "106,2,3,0.2,0.2,0.,0.8,0.2,0.,0.5,0.8,0.;", 0)]).unwrap();
    assert_eq!(l.len(), 4);
    // more points claimed than written, and an unknown IP: warnings naming the entity
    let w = hole(&[(106, "106,1,40,0.,0.1,0.1;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("entity 106 (entry 2)") && w.contains("40")), "{w:?}");
    let w = hole(&[(106, "106,1,1e30,0.,0.1,0.1;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("entity 106 (entry 2)") && w.contains("1e30")), "{w:?}");
    let w = hole(&[(106, "106,7,1,0.,0.1,0.1;", 0)]).unwrap_err();
    assert!(w.iter().any(|w| w.contains("IP = 7")), "{w:?}");
}

const BILINEAR: &str =
    "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;";

#[test]
fn surfaces_take_their_colours_from_definitions_and_standard_numbers() {
    let lin = |c: f32| hitex_core::texture::srgb_to_linear(c);
    let text = iges_file_coloured(&[
        (314, "314,100.,50.,0.,6Horange;", 0, 0),
        (128, BILINEAR, 0, -1),
        (128, BILINEAR, 0, 3),
        (128, BILINEAR, 0, 0),
    ]);
    let m = parse_iges(&text, "c.igs").unwrap();
    assert_eq!(m.surfaces.len(), 3);
    assert!(m.warnings.is_empty(), "a colour definition that is used is not 'skipped': {:?}", m.warnings);
    assert_eq!(m.colors, vec![Some([1.0, lin(0.5), 0.0]), Some([0.0, 1.0, 0.0]), None]);
    // no colours anywhere: none listed
    let m = parse_iges(&iges_file(&[(128, BILINEAR)]), "n.igs").unwrap();
    assert!(m.colors.is_empty());
}

#[test]
fn a_trimmed_surface_without_a_colour_takes_its_base_surfaces() {
    let text = holed_square();
    // the base surface (entry 1) coloured blue through its standard number
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let second = lines.iter().position(|l| l.ends_with("D      2")).unwrap();
    lines[second].replace_range(16..24, &format!("{:>8}", 4));
    let m = parse_iges(&(lines.join("\n") + "\n"), "h.igs").unwrap();
    assert_eq!(m.surfaces.len(), 1);
    assert!(!m.surfaces[0].trim.is_empty());
    assert_eq!(m.colors, vec![Some([0.0, 0.0, 1.0])]);
}

#[test]
fn unreadable_colours_leave_the_default_with_one_warning_naming_the_entry() {
    type Entities<'a> = &'a [(i64, &'a str, usize, i64)];
    let cases: [(Entities, &str); 4] = [
        (&[(128, BILINEAR, 0, -7), (128, BILINEAR, 0, -7)], "colour pointer -7: pointer 7 names no directory entry"),
        (&[(110, "110,0.,0.,0.,1.,0.,0.;", 0, 0), (128, BILINEAR, 0, -1)], "names entity 110, not a colour definition"),
        (&[(314, "314,100.,zz,0.;", 0, 0), (128, BILINEAR, 0, -1)], "field 3 is not a number"),
        (&[(128, BILINEAR, 0, 12)], "colour number 12 is neither"),
    ];
    for (entities, needle) in cases {
        let m = parse_iges(&iges_file_coloured(entities), "w.igs").unwrap();
        assert!(m.colors.is_empty(), "{needle}");
        let w: Vec<&String> = m.warnings.iter().filter(|w| w.contains("colour ignored")).collect();
        assert_eq!(w.len(), 1, "{:?}", m.warnings);
        assert!(w[0].contains(needle) && w[0].contains("directory entry"), "{}", w[0]);
    }
    // the same bad pointer on two surfaces: one warning that counts the other
    let m = parse_iges(&iges_file_coloured(cases[0].0), "w.igs").unwrap();
    assert!(m.warnings.iter().any(|w| w.contains("and 1 more surfaces")), "{:?}", m.warnings);
}

/// The coefficients of entity 114 records, read independently of the
/// reader: (TU, TV, 48 coefficients of each of the (M+1)×(N+1) patches).
fn records_114(text: &str) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut recs: std::collections::BTreeMap<usize, String> = Default::default();
    for l in text.lines().filter(|l| l.len() > 72 && &l[72..73] == "P") {
        recs.entry(l[64..72].trim().parse().unwrap()).or_default().push_str(&l[..64]);
    }
    recs.values()
        .filter(|r| r.starts_with("114,"))
        .map(|r| {
            let f: Vec<f64> =
                r.split(';').next().unwrap().split(',').skip(1).map(|x| x.trim().parse().unwrap()).collect();
            let (m, n) = (f[2] as usize, f[3] as usize);
            (f[4..5 + m].to_vec(), f[5 + m..6 + m + n].to_vec(), f[6 + m + n..].to_vec())
        })
        .collect()
}

#[test]
fn parametric_spline_surfaces_become_exact_bezier_patches() {
    // a real file of four 114 entities (8×3, 6×3, 8×3 and 8×6 bicubic patches)
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cad/surf114.igs");
    let text = std::fs::read_to_string(&path).unwrap();
    let m = parse_iges(&text, "surf114.igs").unwrap();
    assert_eq!(m.surfaces.len(), 114);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    assert_eq!(m.units.as_deref(), Some("inch"));
    let recs = records_114(&text);
    assert_eq!(recs.len(), 4);
    let mut k = 0;
    let mut worst: f64 = 0.0;
    for (tu, tv, c) in &recs {
        let n = tv.len() - 1;
        for i in 0..tu.len() - 1 {
            for j in 0..n {
                let s = &m.surfaces[k];
                assert_eq!(s.range, ((tu[i], tu[i + 1]), (tv[j], tv[j + 1])));
                let at = 48 * (i * (n + 1) + j);
                for step in 0..25 {
                    let (fu, fv) = ((step % 5) as f64 / 4.0, (step / 5) as f64 / 4.0);
                    let (u, v) = (tu[i] + fu * (tu[i + 1] - tu[i]), tv[j] + fv * (tv[j + 1] - tv[j]));
                    let (ds, dt) = (u - tu[i], v - tv[j]);
                    let p = s.surface.point(u, v);
                    for q in 0..3 {
                        let mut want = 0.0;
                        for b in 0..4 {
                            for a in 0..4 {
                                want += c[at + 16 * q + 4 * b + a] * ds.powi(a as i32) * dt.powi(b as i32);
                            }
                        }
                        worst = worst.max((p[q] - want).abs());
                    }
                }
                k += 1;
            }
        }
    }
    // the polynomials themselves, to rounding (the model is about 4 inches across)
    assert!(worst < 1e-11, "{worst}");
    // neighbouring patches meet to the file's six digits
    let (a, b) = (&m.surfaces[0], &m.surfaces[1]);
    let v = a.range.1.1;
    for f in [0.0, 0.3, 1.0] {
        let u = a.range.0.0 + f * (a.range.0.1 - a.range.0.0);
        let (p, q) = (a.surface.point(u, v), b.surface.point(u, v));
        assert!((0..3).all(|t| (p[t] - q[t]).abs() < 1e-5), "{p:?} {q:?}");
    }
}

#[test]
fn malformed_parametric_spline_surfaces_name_the_entry() {
    let patch = |m: &str, n: &str, tu: &str, coef: &str| -> String {
        let mut r = format!("114,3,1,{m},{n},{tu},0.,1.");
        for k in 0..4 * 48 {
            r += &format!(",{}", if k == 5 { coef } else { "0." });
        }
        r + ";"
    };
    for (rec, needle) in [
        (patch("1", "1", "0.,1.", "1."), ""),
        (patch("0", "1", "0.,1.", "1."), "M (u segments) = 0"),
        (patch("40", "1", "0.,1.", "1."), "needs"),
        (patch("1", "1", "1.,1.", "1."), "breakpoints TU do not rise"),
        (patch("1", "1", "0.,1.", "zz"), "coefficient F of x 'zz'"),
    ] {
        let r = parse_iges(&iges_file(&[(114, &rec)]), "s.igs");
        if needle.is_empty() {
            assert_eq!(r.unwrap().surfaces.len(), 1);
            continue;
        }
        let e = r.unwrap_err().to_string();
        assert!(
            e.contains("s.igs") && e.contains("directory entry 1") && e.contains("entity 114") && e.contains(needle),
            "{e}"
        );
    }
}

/// Points of patch `s` on a 9×9 grid of its parameter range.
fn grid(s: &IgesSurface) -> Vec<[f64; 3]> {
    let ((u0, u1), (v0, v1)) = s.range;
    (0..81)
        .map(|k| s.surface.point(u0 + (u1 - u0) * (k % 9) as f64 / 8.0, v0 + (v1 - v0) * (k / 9) as f64 / 8.0))
        .collect()
}

#[test]
fn surfaces_of_revolution_are_exact() {
    // a line parallel to the z axis, turned a whole turn: a cylinder of radius 2
    let m = parse_iges(
        &iges_file(&[
            (110, "110,0.,0.,0.,0.,0.,1.;"),
            (110, "110,2.,0.,0.,2.,0.,3.;"),
            (120, "120,1,3,0.,6.283185307179586;"),
        ]),
        "cyl.igs",
    )
    .unwrap();
    assert_eq!(m.surfaces.len(), 1);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let pts = grid(&m.surfaces[0]);
    assert!(pts.iter().all(|p| ((p[0].hypot(p[1])) - 2.0).abs() < 1e-12 && (-1e-12..=3.0 + 1e-12).contains(&p[2])));
    assert!(pts.iter().any(|p| p[0] < -1.9) && pts.iter().any(|p| p[1] < -1.9), "a whole turn");
    // a half circle (100) about the y axis: a unit sphere
    let m = parse_iges(
        &iges_file(&[
            (110, "110,0.,-1.,0.,0.,1.,0.;"),
            (100, "100,0.,0.,0.,0.,-1.,0.,1.;"),
            (120, "120,1,3,0.,6.283185307179586;"),
        ]),
        "sphere.igs",
    )
    .unwrap();
    let pts = grid(&m.surfaces[0]);
    assert!(pts.iter().all(|p| (p[0].hypot(p[1]).hypot(p[2]) - 1.0).abs() < 1e-12), "{pts:?}");
    // a quarter turn of a line crossing the axis' plane: a cone band between the angles
    let m = parse_iges(
        &iges_file(&[
            (110, "110,0.,0.,0.,0.,0.,1.;"),
            (110, "110,1.,0.,0.,2.,0.,1.;"),
            (120, "120,1,3,0.,1.5707963267948966;"),
        ]),
        "cone.igs",
    )
    .unwrap();
    for p in grid(&m.surfaces[0]) {
        assert!((p[0].hypot(p[1]) - (1.0 + p[2])).abs() < 1e-12 && p[0] > -1e-12 && p[1] > -1e-12, "{p:?}");
    }
}

#[test]
fn tabulated_cylinders_move_their_curve_along_the_generatrix() {
    // a quadratic Bézier (126) moved to 5 above its start, then placed by a matrix (124)
    let bezier = "126,2,2,1,0,1,0,0.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,2.,0.,2.,0.,0.,0.,0.,1.,0.,0.,1.;";
    let m = parse_iges(
        &iges_file_placed(&[
            (126, bezier, 0),
            (124, "124,1.,0.,0.,10.,0.,1.,0.,0.,0.,0.,1.,0.;", 0),
            (122, "122,1,0.,0.,5.;", 3),
        ]),
        "tab.igs",
    )
    .unwrap();
    assert_eq!(m.surfaces.len(), 1);
    let s = &m.surfaces[0];
    assert_eq!(s.range, ((0.0, 1.0), (0.0, 1.0)));
    for k in 0..25 {
        let (t, v) = ((k % 5) as f64 / 4.0, (k / 5) as f64 / 4.0);
        let c = [2.0 * t * (1.0 - t) + 2.0 * t * t, 4.0 * t * (1.0 - t)];
        let p = s.surface.point(t, v);
        let want = [10.0 + c[0], c[1], 5.0 * v];
        assert!((0..3).all(|i| (p[i] - want[i]).abs() < 1e-12), "({t}, {v}): {p:?} {want:?}");
    }
}

#[test]
fn swept_surfaces_that_cannot_be_read_are_skipped_with_a_warning() {
    for (entities, needle) in [
        (
            vec![
                (126, "126,1,1,1,0,1,0,0.,0.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.;"),
                (110, "110,1.,0.,0.,1.,0.,1.;"),
                (120, "120,1,3,0.,1.;"),
            ],
            "not a line (110)",
        ),
        (
            vec![
                (110, "110,0.,0.,0.,0.,0.,1.;"),
                (104, "104,1.,0.,1.,0.,0.,-1.,0.,1.,0.,-1.,0.;"),
                (120, "120,1,3,0.,1.;"),
            ],
            "hitex sweeps lines (110)",
        ),
        (
            vec![(110, "110,0.,0.,0.,0.,0.,1.;"), (110, "110,1.,0.,0.,1.,0.,1.;"), (120, "120,1,3,1.,0.5;")],
            "not within one turn",
        ),
        (vec![(110, "110,1.,0.,0.,1.,0.,1.;"), (122, "122,1,1.,0.,0.;")], "zero length"),
        (vec![(110, "110,1.,0.,0.,1.,0.,1.;"), (122, "122,7,1.,0.,0.;")], "names no directory entry"),
        (
            vec![(110, "110,1.,0.,0.,1.,zz,1.;"), (122, "122,1,1.,0.,5.;")],
            "entity 110 (entry 1): field 6 is not a number",
        ),
    ] {
        let mut all = entities.clone();
        all.push((128, BILINEAR));
        let m = parse_iges(&iges_file(&all), "w.igs").unwrap();
        assert_eq!(m.surfaces.len(), 1, "the rest of the file loads: {needle}");
        let w: Vec<&String> = m.warnings.iter().filter(|w| w.contains("skipped:")).collect();
        assert!(
            w.len() == 1 && w[0].contains("directory entry") && w[0].contains(needle),
            "{needle}: {:?}",
            m.warnings
        );
    }
}

#[test]
fn a_file_of_curves_only_says_so() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cad/curve_geom_plate.igs");
    let e = load_iges(&path).unwrap_err().to_string();
    assert!(
        e.contains("curve_geom_plate.igs") && e.contains("126 (rational B-spline curve)") && e.contains("114"),
        "{e}"
    );
}

#[test]
fn tiny_file_reads_without_repairs() {
    let m = parse_iges(&tiny(BILINEAR), "tiny.igs").unwrap();
    assert_eq!(m.surfaces.len(), 1);
    assert!(m.repairs.is_empty(), "{:?}", m.repairs);
    let s = &m.surfaces[0].surface;
    assert_eq!((s.degree_u, s.degree_v, s.count_u, s.count_v), (1, 1, 2, 2));
    let p = s.point(0.5, 0.5);
    assert!((p[0] - 0.5).abs() < 1e-12 && (p[1] - 0.5).abs() < 1e-12 && (p[2] - 0.25).abs() < 1e-12, "{p:?}");
}

#[test]
fn malformed_records_name_entity_and_record() {
    let cases = [
        ("128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.;", "needs"),
        ("128,1,1,0,1,0,0,1,0,0,0.,1.,0.,0.,1.,1.;", "M1"),
        (
            "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,-1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
            "weight",
        ),
        (
            "128,1,1,1,1,0,0,1,0,0,0.,1.,0.5,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
            "knot",
        ),
        (
            "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,zz,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
            "'zz'",
        ),
        ("128,999999,999999,3,3,0,0,1,0,0,0.;", "declare more control points"),
        ("128,1e300,1,3,3,0,0,1,0,0,0.;", "K1 1e300 is out of range"),
        ("126,1,1;", "directory says entity 128"),
    ];
    for (rec, needle) in cases {
        let e = parse_iges(&tiny(rec), "bad.igs").unwrap_err().to_string();
        assert!(e.contains("bad.igs") && e.contains("directory entry 1") && e.contains(needle), "{rec}: {e}");
    }
    // truncated lines and garbage
    let e = parse_iges("short line\n", "t.igs").unwrap_err().to_string();
    assert!(e.contains("line 1"), "{e}");
    let e = parse_iges("", "empty.igs").unwrap_err().to_string();
    assert!(e.contains("no directory"), "{e}");
}

#[test]
fn teapot_reads_with_repairs_and_matches_reference_samples() {
    // kept in the repository (the same files as ../shared/data/nurbs): the
    // samples were evaluated by an independent library
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/teapot.igs");
    let refs = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/teapot_reference_samples.jsonl");
    let m = load_iges(&path).unwrap();
    assert_eq!(m.surfaces.len(), 32);
    assert!(!m.repairs.is_empty(), "the teapot file is known to be inconsistent");
    let text = std::fs::read_to_string(&refs).unwrap();
    let mut n = 0;
    for l in text.lines() {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        let patch = v["patch"].as_u64().unwrap() as usize;
        let (u, w) = (v["u"].as_f64().unwrap(), v["v"].as_f64().unwrap());
        let s = &m.surfaces[patch].surface;
        let p = s.point(u, w);
        let nrm = s.normal(u, w);
        for t in 0..3 {
            assert!((p[t] - v["point"][t].as_f64().unwrap()).abs() < 1e-9, "patch {patch} ({u}, {w}): {p:?}");
            assert!((nrm[t] - v["normal"][t].as_f64().unwrap()).abs() < 1e-7, "patch {patch} ({u}, {w}): {nrm:?}");
        }
        n += 1;
    }
    assert_eq!(n, 200);
}
