use super::*;
use std::io::Write;

fn tmpdir(name: &str) -> crate::test_dir::TestDir {
    crate::test_dir::TestDir::fresh(&format!("io-btf-images-{name}"))
}

fn noise(seed: u32, n: usize) -> Vec<u8> {
    let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 24) as u8
        })
        .collect()
}

fn small_btf() -> Btf {
    let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
    let n = checked_size(&grid, 4, 4).unwrap();
    Btf::new(grid, 4, 4, noise(1, n)).unwrap()
}

fn png(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
    use image::ImageEncoder;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf).write_image(rgb, w, h, image::ExtendedColorType::Rgb8).unwrap();
    buf
}

fn quiet(_: usize, _: usize) {}

#[test]
fn btf_names_parse_leniently() {
    assert_eq!(parse_name("tl015 pl060 tv030 pv120.jpg"), Name::Image([15.0, 60.0, 30.0, 120.0]));
    assert_eq!(parse_name("TL000_PL000_TV075_PV345.PNG"), Name::Image([0.0, 0.0, 75.0, 345.0]));
    assert_eq!(parse_name("wool_tv030_pv120_tl015_pl060.jpeg"), Name::Image([15.0, 60.0, 30.0, 120.0]));
    assert_eq!(parse_name("tl15.5 pl0 tv0 pv0.png"), Name::Image([15.5, 0.0, 0.0, 0.0]));
    assert_eq!(parse_name("tl000_pl000_tv000_pv000.exr"), Name::Exr([0.0; 4]));
    for bad in [
        "readme.txt",
        "tl000 pl000 tv000.png",
        "tl000 pl000 tv000 pv000.txt",
        "._tl000 pl000 tv000 pv000.jpg",
        "tl000 tl010 pl000 tv000 pv000.png",
        "tl000 pl000 tv000 pv000",
    ] {
        assert_eq!(parse_name(bad), Name::Other, "{bad}");
    }
}

#[test]
fn btf_image_set_round_trips_in_both_conventions() {
    let btf = small_btf();
    for (conv, sample) in
        [(Convention::Ubo, "tl030 pl090 tv060 pv270.png"), (Convention::Utia, "tl030_pl090_tv060_pv270.png")]
    {
        let d = tmpdir(&format!("rt-{conv:?}"));
        assert_eq!(export_image_set(&btf, &d.join("set"), conv).unwrap(), 144);
        assert!(d.join("set").join(sample).is_file());
        let calls = std::cell::Cell::new(0);
        let (back, rep) = import_image_set(&d.join("set"), None, None, &|_, t| {
            calls.set(calls.get() + 1);
            assert_eq!(t, 288);
        })
        .unwrap();
        assert_eq!(calls.get(), 288);
        assert!(!rep.resampled, "{}", rep.method);
        assert!(rep.method.starts_with("direct"), "{}", rep.method);
        assert_eq!((rep.images, rep.view_dirs, rep.light_dirs), (144, 12, 12));
        assert!(rep.missing.is_empty() && rep.duplicated.is_empty() && rep.ignored.is_empty());
        assert_eq!(back, btf);
        // the same grid asked for explicitly
        let (again, _) = import_image_set(&d.join("set"), Some(btf.grid().clone()), None, &quiet).unwrap();
        assert_eq!(again, btf);
    }
}

#[test]
fn btf_image_set_from_a_zip_with_folders() {
    let btf = small_btf();
    let d = tmpdir("zip");
    export_image_set(&btf, &d.join("set"), Convention::Ubo).unwrap();
    let zp = d.join("set.zip");
    let mut z = zip::ZipWriter::new(std::fs::File::create(&zp).unwrap());
    let opts = zip::write::SimpleFileOptions::default();
    z.add_directory("wool/", opts).unwrap();
    let mut names: Vec<_> = std::fs::read_dir(d.join("set")).unwrap().map(|e| e.unwrap().file_name()).collect();
    names.sort();
    for (i, name) in names.iter().enumerate() {
        let bytes = std::fs::read(d.join("set").join(name)).unwrap();
        let mut entry = format!("wool/rectified/{}", name.to_string_lossy());
        if i % 2 == 0 {
            entry = entry.to_uppercase();
        }
        z.start_file(entry, opts).unwrap();
        z.write_all(&bytes).unwrap();
    }
    z.start_file("wool/readme.txt", opts).unwrap();
    z.write_all(b"Bonn BTF").unwrap();
    z.start_file("__MACOSX/wool/._tl000 pl000 tv000 pv000.png", opts).unwrap();
    z.write_all(b"resource fork").unwrap();
    z.finish().unwrap();
    let (back, rep) = import_image_set(&zp, None, None, &quiet).unwrap();
    assert_eq!(back, btf);
    assert_eq!(rep.ignored.len(), 2, "{:?}", rep.ignored);
    assert!(rep.ignored.iter().any(|n| n.ends_with("readme.txt")));
    assert!(!rep.resampled);
}

/// Seven directions on three rings, all 49 (view, light) images.
fn irregular_set(dir: &Path) -> Vec<(Dir, Dir, Vec<u8>)> {
    let dirs = [(0, 0), (30, 0), (30, 120), (30, 240), (60, 60), (60, 180), (60, 300)];
    std::fs::create_dir_all(dir).unwrap();
    let mut out = Vec::new();
    for (i, &(tv, pv)) in dirs.iter().enumerate() {
        for (j, &(tl, pl)) in dirs.iter().enumerate() {
            let rgb = noise((i * 7 + j) as u32 + 100, 4 * 4 * 3);
            let name = Convention::Ubo.file_name(tl, pl, tv, pv).replace(".png", ".jpg");
            // JPEG names with PNG content: the content decides
            std::fs::write(dir.join(name), png(4, 4, &rgb)).unwrap();
            out.push((Dir::new(tv as f32, pv as f32), Dir::new(tl as f32, pl as f32), rgb));
        }
    }
    out
}

#[test]
fn btf_irregular_sets_are_resampled() {
    let d = tmpdir("irregular");
    let set = irregular_set(&d.join("set"));
    let (btf, rep) = import_image_set(&d.join("set"), None, None, &quiet).unwrap();
    assert!(rep.resampled);
    assert!(rep.method.contains("inverse-distance") && rep.method.contains("clamped"), "{}", rep.method);
    assert_eq!((rep.images, rep.view_dirs, rep.light_dirs), (49, 7, 7));
    assert!(rep.missing.is_empty());
    assert_eq!(btf.grid(), &AngularGrid::paper());
    let g = btf.grid();
    // measured directions on the paper grid: (0, 0) → (0, 0); (30, 0) → (3, 0); (60, 180) → (6, 8)
    for ((tv, pv), (tl, pl)) in [((0, 0), (0, 0)), ((3, 0), (6, 8)), ((6, 8), (3, 0)), ((0, 5), (6, 8))] {
        let (v, l) = (g.direction(tv, pv), g.direction(tl, pl));
        let vd = Dir::new(g.theta_deg()[tv], if tv == 0 { 0.0 } else { g.phi_deg(pv) });
        let ld = Dir::new(g.theta_deg()[tl], if tl == 0 { 0.0 } else { g.phi_deg(pl) });
        let (_, _, want) = set.iter().find(|(a, b, _)| a.key() == vd.key() && b.key() == ld.key()).unwrap();
        for (a, b) in btf.image(v, l).iter().zip(want) {
            assert!((*a as i32 - *b as i32).abs() <= 1, "{a} vs {b}");
        }
    }
    // a grazing target (θ = 70°) blends the 60° ring at its azimuth: (60, 180) is exact there
    let (v, l) = (g.direction(7, 8), g.direction(0, 0));
    let (_, _, want) = set.iter().find(|(a, b, _)| a.key() == (6000, 18000) && b.key() == (0, 0)).unwrap();
    assert_eq!(btf.image(v, l), &want[..]);
    // size: a 2x2 box filter of every image
    let (small, _) = import_image_set(&d.join("set"), None, Some(2), &quiet).unwrap();
    assert_eq!((small.width(), small.height()), (2, 2));
    let lut = linear_lut();
    let want = fit(set[0].2.clone(), 4, 4, Some(2), |c: u8| lut[c as usize], linear_to_srgb_u8);
    let mean = (lut[set[0].2[0] as usize]
        + lut[set[0].2[3] as usize]
        + lut[set[0].2[12] as usize]
        + lut[set[0].2[15] as usize])
        / 4.0;
    assert_eq!(want[0], linear_to_srgb_u8(mean));
    assert!(small.image(0, 0).iter().zip(&want).all(|(a, b)| (*a as i32 - *b as i32).abs() <= 1));
}

#[test]
fn btf_image_set_sparse_and_duplicated() {
    let d = tmpdir("sparse");
    let set = irregular_set(&d.join("set"));
    // drop one combination and duplicate another under the other convention
    std::fs::remove_file(d.join("set").join("tl030 pl120 tv060 pv300.jpg")).unwrap();
    std::fs::write(d.join("set").join("tl000_pl000_tv000_pv000.png"), png(4, 4, &set[1].2)).unwrap();
    std::fs::write(d.join("set").join("notes.md"), b"x").unwrap();
    let (btf, rep) = import_image_set(&d.join("set"), None, None, &quiet).unwrap();
    assert_eq!(rep.missing, vec!["tl030 pl120 tv060 pv300".to_string()]);
    assert_eq!(rep.duplicated, vec!["tl000_pl000_tv000_pv000.png".to_string()]);
    assert_eq!(rep.ignored, vec!["notes.md".to_string()]);
    assert_eq!(rep.images, 48);
    // the first file is kept
    assert_eq!(btf.image(0, 0), &set[0].2[..]);
}

#[test]
fn btf_image_set_errors_name_the_file() {
    let btf = small_btf();
    let d = tmpdir("errors");
    let set = d.join("set");
    export_image_set(&btf, &set, Convention::Utia).unwrap();
    // missing image of a regular set
    std::fs::remove_file(set.join("tl030_pl090_tv060_pv270.png")).unwrap();
    let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl030 pl090 tv060 pv270") && e.contains("1 of its 144"), "{e}");
    export_image_set(&btf, &set, Convention::Utia).unwrap();
    // corrupt image
    let f = set.join("tl000_pl000_tv030_pv180.png");
    std::fs::write(&f, b"\x89PNG\r\n\x1a\n garbage").unwrap();
    let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl000_pl000_tv030_pv180.png"), "{e}");
    // a different size
    std::fs::write(&f, png(2, 2, &[9; 12])).unwrap();
    let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl000_pl000_tv030_pv180.png") && e.contains("same size"), "{e}");
    std::fs::remove_file(&f).unwrap();
    // an EXR among PNGs
    std::fs::write(set.join("tl000_pl000_tv030_pv180.exr"), b"v/1\x01").unwrap();
    let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
    assert!(e.contains("mixes OpenEXR and 8-bit") && e.contains("tl000_pl000_tv030_pv180.exr"), "{e}");
    // nothing usable; not a folder or zip; missing path; absurd size
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::write(empty.join("a.txt"), b"x").unwrap();
    assert!(import_image_set(&empty, None, None, &quiet).unwrap_err().to_string().contains("1 files ignored"));
    let e = import_image_set(&empty.join("a.txt"), None, None, &quiet).unwrap_err().to_string();
    assert!(e.contains("a.txt") && e.contains("zip"), "{e}");
    assert!(import_image_set(&d.join("nope"), None, None, &quiet).unwrap_err().to_string().contains("nope"));
    assert!(import_image_set(&empty, None, Some(0), &quiet).is_err());
    // a BTF too large for the target grid is refused before the images are read
    let set2 = d.join("set2");
    irregular_set(&set2);
    let e = import_image_set(&set2, None, Some(1024), &quiet).unwrap_err().to_string();
    assert!(e.contains("too large"), "{e}");
}

/// An analytic HDR value of texel `i` of image (view, light): above 1
/// for many texels, never representable in 8 bits.
fn hdr_value(view: usize, light: usize, i: usize) -> f32 {
    0.003 + 0.37 * (i % 7) as f32 + 1.9 * light as f32 / 11.0 + 0.011 * view as f32 + 0.5 * (i % 3) as f32
}

fn hdr_btf() -> Btf {
    let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
    let d = grid.directions();
    let n = 4 * 4 * 3;
    let linear: Vec<f32> = (0..d * d * n).map(|k| hdr_value(k / n / d, k / n % d, k % n)).collect();
    Btf::from_linear(grid, 4, 4, &linear).unwrap()
}

/// An EXR file of named channels from f32 planes (stored as `half` or f32).
fn exr_file(w: usize, h: usize, planes: &[(&str, Vec<f32>)], half: bool) -> Vec<u8> {
    use exr::prelude::*;
    let chans: Vec<AnyChannel<FlatSamples>> = planes
        .iter()
        .map(|(n, v)| {
            let data = if half {
                FlatSamples::F16(v.iter().map(|&x| f16::from_f32(x)).collect())
            } else {
                FlatSamples::F32(v.clone())
            };
            AnyChannel::new(*n, data)
        })
        .collect();
    let layer =
        Layer::new((w, h), LayerAttributes::default(), Encoding::FAST_LOSSLESS, AnyChannels::sort(chans.into()));
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

#[test]
fn btf_exr_sets_round_trip_at_half_precision() {
    let btf = hdr_btf();
    assert!(btf.is_hdr());
    let h = btf.hdr().unwrap();
    // values above 1: the display copy is scaled down by the 99.9th percentile
    assert!(h.ldr_scale < 0.5, "{}", h.ldr_scale);
    let d = tmpdir("exr-rt");
    let set = d.join("set");
    let n = export_image_set_as(&btf, &set, Convention::Utia, SetFormat::Exr, &mut |_, _| {}).unwrap();
    assert_eq!(n, 144);
    assert!(set.join("tl030_pl090_tv060_pv270.exr").is_file());
    let (back, rep) = import_image_set(&set, None, None, &quiet).unwrap();
    assert!(rep.hdr && rep.clamped == 0 && !rep.resampled, "{rep:?}");
    // the half floats come back bit for bit, so the values are those written to half precision
    assert_eq!(back.hdr(), btf.hdr());
    assert_eq!(back, btf);
    let g = btf.grid().directions();
    for (k, &hb) in back.hdr().unwrap().half.iter().enumerate() {
        let want = hdr_value(k / 48 / g, k / 48 % g, k % 48);
        let got = hitex_core::btf::dataset::half_value(hb);
        assert!((got - want).abs() <= want * 4.9e-4, "{k}: {got} vs {want}");
    }
    // PNG export writes the display copy; 8-bit BTFs export to EXR decoded from sRGB
    let png_set = d.join("png");
    export_image_set_as(&btf, &png_set, Convention::Utia, SetFormat::Png, &mut |_, _| {}).unwrap();
    let (ldr, rep) = import_image_set(&png_set, None, None, &quiet).unwrap();
    assert!(!rep.hdr && !ldr.is_hdr());
    assert_eq!(ldr.texels(), btf.texels());
    let small = small_btf();
    let e8 = d.join("e8");
    export_image_set_as(&small, &e8, Convention::Ubo, SetFormat::Exr, &mut |_, _| {}).unwrap();
    let (lifted, _) = import_image_set(&e8, None, None, &quiet).unwrap();
    assert!(lifted.is_hdr());
    assert_eq!(lifted.texels(), small.texels(), "sRGB → half → sRGB keeps every 8-bit code");
}

#[test]
fn btf_exr_float_xyz_grey_and_utia_folders() {
    let grid = AngularGrid::new(vec![0.0, 45.0], 2).unwrap();
    let d = tmpdir("exr-kinds");
    let (w, h) = (3, 2);
    let rgb_of = |k: usize| [0.2 + 0.1 * k as f32, 1.5 + 0.05 * k as f32, 0.7];
    // XYZ of a linear sRGB colour (the inverse of the reader's matrix)
    let to_xyz = |c: [f32; 3]| {
        let m =
            [[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.119192, 0.9503041]];
        [0, 1, 2].map(|r| m[r][0] * c[0] + m[r][1] * c[1] + m[r][2] * c[2])
    };
    for kind in ["float", "xyz", "grey"] {
        let set = d.join(kind);
        for (vi, &(tv, pv)) in [(0, 0), (45, 0), (45, 180)].iter().enumerate() {
            let _ = vi;
            // UTIA: one folder per view, the file names carry the light
            let folder = set.join(format!("tv{tv:03}_pv{pv:03}"));
            std::fs::create_dir_all(&folder).unwrap();
            for &(tl, pl) in &[(0, 0), (45, 0), (45, 180)] {
                let k = (tv + pv + tl + pl) as usize / 45;
                let c = rgb_of(k);
                let planes: Vec<(&str, Vec<f32>)> = match kind {
                    "float" => vec![("R", vec![c[0]; w * h]), ("G", vec![c[1]; w * h]), ("B", vec![c[2]; w * h])],
                    "xyz" => {
                        let x = to_xyz(c);
                        vec![("X", vec![x[0]; w * h]), ("Y", vec![x[1]; w * h]), ("Z", vec![x[2]; w * h])]
                    }
                    _ => vec![("Y", vec![c[1]; w * h])],
                };
                std::fs::write(
                    folder.join(format!("tl{tl:03}_pl{pl:03}.exr")),
                    exr_file(w, h, &planes, kind != "float"),
                )
                .unwrap();
            }
        }
        let (btf, rep) = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap();
        // θ = 0 is on the grid once per azimuth: filled by exact copies (a resampling)
        assert!(rep.hdr && rep.ignored.is_empty(), "{kind}: {rep:?}");
        assert_eq!(rep.images, 9);
        let g = btf.grid();
        for (v, &(tv, pv)) in [(0u32, 0u32), (45, 0), (45, 180)].iter().enumerate() {
            for (l, &(tl, pl)) in [(0u32, 0u32), (45, 0), (45, 180)].iter().enumerate() {
                let _ = (v, l);
                let dir = |t: u32, p: u32| if t == 0 { 0 } else { g.phi_count() + (p / 180) as usize };
                let got = btf.texel_linear(dir(tv, pv), dir(tl, pl), 2, 1);
                let c = rgb_of((tv + pv + tl + pl) as usize / 45);
                let want = if kind == "grey" { [c[1]; 3] } else { c };
                for ch in 0..3 {
                    assert!((got[ch] - want[ch]).abs() <= 4e-3 * want[ch].max(0.1), "{kind} {ch}: {got:?} vs {want:?}");
                }
            }
        }
    }
}

#[test]
fn exr_chromaticities_map_the_files_white_to_srgb_white() {
    // Rec. 709 itself; CIE XYZ stored as RGB (white E, a blue of y = 0); ACES AP0 (white ≈ D60)
    let xyz_e = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [1.0 / 3.0, 1.0 / 3.0]];
    let ap0 = [[0.7347, 0.2653], [0.0, 1.0], [0.0001, -0.077], [0.32168, 0.33767]];
    for c in [REC709, xyz_e, ap0] {
        let m = mul3(&XYZ_TO_SRGB, &rgb_to_xyz(&c).unwrap());
        for (r, row) in m.iter().enumerate() {
            let white: f64 = row.iter().sum();
            assert!((white - 1.0).abs() < 2e-3, "{c:?}: row {r} maps white to {white}");
        }
    }
    // Rec. 709 primaries give the identity
    let m = mul3(&XYZ_TO_SRGB, &rgb_to_xyz(&REC709).unwrap());
    for (r, row) in m.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            assert!((v - if r == k { 1.0 } else { 0.0 }).abs() < 2e-3, "{m:?}");
        }
    }
    // a degenerate white is refused
    assert!(rgb_to_xyz(&[[0.64, 0.33], [0.3, 0.6], [0.15, 0.06], [0.3, 0.0]]).is_none());
}

#[test]
fn btf_exr_bad_input_is_refused_or_clamped_and_said() {
    let d = tmpdir("exr-bad");
    let grid = AngularGrid::new(vec![0.0], 1).unwrap();
    let one = |set: &Path, planes: &[(&str, Vec<f32>)], w: usize, h: usize| {
        std::fs::create_dir_all(set).unwrap();
        std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), exr_file(w, h, planes, true)).unwrap();
    };
    // missing channels: named
    let set = d.join("missing");
    one(&set, &[("R", vec![1.0; 4]), ("G", vec![1.0; 4])], 2, 2);
    let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl000_pl000_tv000_pv000.exr") && e.contains("G, R") && e.contains("needs R, G and B"), "{e}");
    // NaN, infinite and negative values: clamped and counted
    let set = d.join("nan");
    one(
        &set,
        &[("R", vec![f32::NAN, 1.0, -2.0, 0.5]), ("G", vec![f32::INFINITY, 0.0, 0.0, 0.0]), ("B", vec![0.25; 4])],
        2,
        2,
    );
    let (btf, rep) = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap();
    assert_eq!(rep.clamped, 3, "{rep:?}");
    assert_eq!(rep.clamped_first.as_deref(), Some("tl000_pl000_tv000_pv000.exr"));
    assert_eq!(btf.texel_linear(0, 0, 0, 0), [0.0, 65504.0, 0.25]);
    assert_eq!(btf.texel_linear(0, 0, 0, 1)[0], 0.0);
    // mixed sizes
    let set = d.join("sizes");
    let g2 = AngularGrid::new(vec![0.0, 40.0], 1).unwrap();
    std::fs::create_dir_all(&set).unwrap();
    let rgb = |n: usize| vec![("R", vec![0.5; n]), ("G", vec![0.5; n]), ("B", vec![0.5; n])];
    for (i, (tl, tv)) in [(0, 0), (0, 40), (40, 0), (40, 40)].iter().enumerate() {
        let (w, h) = if i == 3 { (3, 2) } else { (2, 2) };
        std::fs::write(set.join(format!("tl{tl:03}_pl000_tv{tv:03}_pv000.exr")), exr_file(w, h, &rgb(w * h), true))
            .unwrap();
    }
    let e = import_image_set(&set, Some(g2), None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl040_pl000_tv040_pv000.exr") && e.contains("same size"), "{e}");
    // not an EXR at all; a truncated one
    let set = d.join("junk");
    std::fs::create_dir_all(&set).unwrap();
    std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), b"v/1\x01junk").unwrap();
    let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
    assert!(e.contains("tl000_pl000_tv000_pv000.exr") && e.contains("OpenEXR"), "{e}");
    let good = exr_file(4, 4, &rgb(16), true);
    for cut in [20, good.len() / 2, good.len() - 3] {
        std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), &good[..cut]).unwrap();
        let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl000_pl000_tv000_pv000.exr"), "{cut}: {e}");
    }
}

#[test]
fn btf_exr_sets_resample_in_linear_light() {
    // an irregular HDR set: the blend is in linear values, above 1 kept
    let d = tmpdir("exr-resample");
    let set = d.join("set");
    std::fs::create_dir_all(&set).unwrap();
    let rgb = |v: f32| vec![("R", vec![v; 4]), ("G", vec![v; 4]), ("B", vec![v; 4])];
    for (tv, pv) in [(0, 0), (20, 0), (20, 120), (20, 240)] {
        for (tl, pl) in [(0, 0), (20, 0), (20, 120), (20, 240)] {
            std::fs::write(
                set.join(format!("tl{tl:03}_pl{pl:03}_tv{tv:03}_pv{pv:03}.exr")),
                exr_file(2, 2, &rgb(4.0), true),
            )
            .unwrap();
        }
    }
    let target = AngularGrid::new(vec![0.0, 10.0], 4).unwrap();
    let (btf, rep) = import_image_set(&set, Some(target), None, &quiet).unwrap();
    assert!(rep.resampled && rep.hdr, "{rep:?}");
    for h in &btf.hdr().unwrap().half {
        assert_eq!(hitex_core::btf::dataset::half_value(*h), 4.0);
    }
}

#[test]
fn btf_export_refuses_colliding_names() {
    let grid = AngularGrid::new(vec![10.0, 10.4], 2).unwrap();
    let btf = Btf::zeroed(grid, 1, 1).unwrap();
    let d = tmpdir("collide");
    assert!(export_image_set(&btf, &d.join("x"), Convention::Ubo).unwrap_err().to_string().contains("collide"));
}
