//! The bad-input catalogue: every class of bad input tried here, run through
//! the `hitex` binary, with what the user sees. The table in
//! `docs/bad-input.md` is generated from these cases (`HITEX_BLESS=1`
//! rewrites it), and this test fails when the two differ — so the catalogue
//! cannot drift from the behaviour.

mod common;

use common::{Tmpfs, error_lines, hitex, tmp};
use std::path::Path;

/// What a case needs beyond the binary.
#[derive(Clone, Copy, PartialEq)]
enum Needs {
    Nothing,
    /// A tmpfs of its own (root).
    Mount,
    /// A GPU adapter.
    Gpu,
}

struct Case {
    input: &'static str,
    wrong: &'static str,
    args: Vec<String>,
    env: Vec<(&'static str, &'static str)>,
    needs: Needs,
}

fn s(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

fn cases(d: &Path, mounts: &mut Vec<Tmpfs>) -> Vec<Case> {
    let w = |name: &str, bytes: &[u8]| {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        s(&p)
    };
    let out = s(&d.join("out.png"));
    let c = |input, wrong, args: &[&str]| Case {
        input,
        wrong,
        args: args.iter().map(|a| a.to_string()).collect(),
        env: Vec::new(),
        needs: Needs::Nothing,
    };
    let mut v = Vec::new();
    // scenes
    let f = w("unknown-key.toml", b"[camera]\nposition = [0, 1, 4]\ntarget = [0, 0, 0]\nzoom = 2\n");
    v.push(c("scene TOML", "unknown key", &["render", &f, "-o", &out]));
    let f = w("nan.toml", b"[camera]\nposition = [0, nan, 4]\ntarget = [0, 0, 0]\n");
    v.push(c("scene TOML", "NaN coordinate", &["render", &f, "-o", &out]));
    let f = w("same.toml", b"[camera]\nposition = [1, 2, 3]\ntarget = [1, 2, 3]\n");
    v.push(c("scene TOML", "camera at its target", &["render", &f, "-o", &out]));
    let f = w(
        "missing-mesh.toml",
        b"[camera]\nposition = [0, 1, 4]\ntarget = [0, 0, 0]\n[[object]]\nmesh = \"nowhere.obj\"\n",
    );
    v.push(c("scene TOML", "mesh file missing", &["render", &f, "-o", &out]));
    // NURBS files
    let f = w("garbage.igs", b"this is not IGES\n");
    v.push(c("IGES", "not IGES at all", &["nurbs", "info", &f]));
    let f = w("trunc.json", br#"{"format": "hitex-nurbs", "version": 1, "patches": [{"degree": [3, 3], "count": [4, "#);
    v.push(c("hitex NURBS JSON", "truncated", &["nurbs", "info", &f]));
    let f = w("bad.obj", b"cstype bspline\ndeg 3 3\nsurf 0 1 0 1 1 2 3\nparm u 0 0 1 1\nend\n");
    v.push(c("OBJ free-form", "control points missing", &["nurbs", "info", &f]));
    // BTF
    let mut h = b"HBTF".to_vec();
    h.extend_from_slice(&[1, 0, 0, 0]);
    let f = w("short.hbtf", &h);
    v.push(c(".hbtf", "header cut short", &["btf", "info", &f]));
    let mut h = b"HBTF".to_vec();
    for x in [1u32, 76, 1024, 1024, 8, 16, 0] {
        h.extend_from_slice(&x.to_le_bytes());
    }
    for t in 0..8 {
        h.extend_from_slice(&(t as f32 * 10.0).to_le_bytes());
    }
    h.extend_from_slice(&(1024u64 * 1024 * 16384 * 3).to_le_bytes());
    h.extend_from_slice(&0u32.to_le_bytes());
    let f = w("huge.hbtf", &h);
    v.push(c(".hbtf", "header claims 1024×1024 texels × 16,384 images", &["btf", "info", &f]));
    let mut h = b"HBTF".to_vec();
    for x in [2u32, 92, 4, 4, 1, 1, 6] {
        h.extend_from_slice(&x.to_le_bytes());
    }
    h.extend_from_slice(&0f32.to_le_bytes());
    h.resize(200, 0);
    let f = w("flags.hbtf", &h);
    v.push(c(".hbtf", "version 2 with an unknown flag bit", &["btf", "info", &f]));
    let f = w("magic.hbtf", b"GIF89a certainly not a BTF file at all");
    v.push(c(".hbtf", "wrong magic", &["btf", "info", &f]));
    v.push(c(
        "BTF grid",
        "polar angles decreasing",
        &["btf", "synth", "knit", "-o", &s(&d.join("x.hbtf")), "--theta", "30,10"],
    ));
    v.push(c("BTF material", "unknown name", &["btf", "synth", "velvet", "-o", &s(&d.join("x.hbtf"))]));
    let set = d.join("set");
    std::fs::create_dir_all(&set).unwrap();
    image::RgbImage::new(4, 4).save(set.join("tl000_pl000_tv000_pv000.png")).unwrap();
    image::RgbImage::new(8, 8).save(set.join("tl000_pl000_tv000_pv180.png")).unwrap();
    v.push(c("BTF image set", "images of different sizes", &["btf", "import", &s(&set), "-o", &s(&d.join("x.hbtf"))]));
    let exr = |planes: &[(&str, f32)], w: usize| {
        use exr::prelude::*;
        let chans: Vec<AnyChannel<FlatSamples>> =
            planes.iter().map(|&(n, v)| AnyChannel::new(n, FlatSamples::F16(vec![f16::from_f32(v); w * 2]))).collect();
        let layer =
            Layer::new((w, 2), LayerAttributes::default(), Encoding::FAST_LOSSLESS, AnyChannels::sort(chans.into()));
        let mut out = std::io::Cursor::new(Vec::new());
        Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
        out.into_inner()
    };
    let set = d.join("exr-rg");
    std::fs::create_dir_all(&set).unwrap();
    std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), exr(&[("R", 1.0), ("G", 2.0)], 2)).unwrap();
    v.push(c("BTF EXR set", "channels R and G only", &["btf", "import", &s(&set), "-o", &s(&d.join("x.hbtf"))]));
    let set = d.join("exr-mixed");
    std::fs::create_dir_all(&set).unwrap();
    std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), exr(&[("R", 1.0), ("G", 2.0), ("B", 3.0)], 2)).unwrap();
    image::RgbImage::new(2, 2).save(set.join("tl000_pl000_tv000_pv180.png")).unwrap();
    v.push(c("BTF EXR set", "OpenEXR mixed with PNG", &["btf", "import", &s(&set), "-o", &s(&d.join("x.hbtf"))]));
    let set = d.join("exr-cut");
    std::fs::create_dir_all(&set).unwrap();
    let full = exr(&[("R", 1.0), ("G", 2.0), ("B", 3.0)], 64);
    std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), &full[..full.len() / 2]).unwrap();
    v.push(c("BTF EXR set", "truncated EXR file", &["btf", "import", &s(&set), "-o", &s(&d.join("x.hbtf"))]));
    let set = d.join("exr-sizes");
    std::fs::create_dir_all(&set).unwrap();
    std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), exr(&[("R", 1.0), ("G", 2.0), ("B", 3.0)], 2)).unwrap();
    std::fs::write(set.join("tl000_pl000_tv000_pv180.exr"), exr(&[("R", 1.0), ("G", 2.0), ("B", 3.0)], 3)).unwrap();
    v.push(c("BTF EXR set", "images of different sizes", &["btf", "import", &s(&set), "-o", &s(&d.join("x.hbtf"))]));
    // terrain
    let f = w("trunc.tif", b"II*\x00\x08\x00\x00\x00\x10\x00");
    v.push(c("GeoTIFF DEM", "truncated", &["terrain", "render", "--dem", &f, "-o", &out]));
    let f = w("N00E000.hgt", &[0u8; 1001]);
    v.push(c("SRTM .hgt", "size is no SRTM grid", &["terrain", "render", "--dem", &f, "-o", &out]));
    let f = w("bad.asc", b"ncols 3\nnrows two\n");
    v.push(c("ESRI ASCII grid", "header value not a number", &["terrain", "render", "--dem", &f, "-o", &out]));
    let f = w(
        "nodata.asc",
        b"ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n-9999 -9999\n-9999 -9999\n",
    );
    v.push(c("ESRI ASCII grid", "every sample nodata", &["terrain", "render", "--dem", &f, "-o", &out]));
    let f = w("bad.npy", b"\x93NUMPY\x01\x00\x10\x00{'descr': '<f4',");
    v.push(c("numpy .npy", "header cut short", &["terrain", "render", "--dem", &f, "-o", &out]));
    v.push(c(
        "GeoTIFF DEM",
        "header claims 16384² float samples, file of 138 bytes",
        &["terrain", "render", "--dem", &w("claim.tif", &tiff_claim()), "-o", &out],
    ));
    // georeferencing and coordinate systems
    let geo_keys = [1024, 0, 1, 2, 2048, 0, 1, 4326];
    let sheared = [30.0, 5.0, 0.0, 4e5, 0.0, -30.0, 0.0, 5e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let f = w("sheared.tif", &georef_tiff(&[(34264, &sheared)], &[1024, 0, 1, 1, 3072, 0, 1, 32632]));
    v.push(c(
        "GeoTIFF DEM",
        "rotated or sheared (ModelTransformation)",
        &["terrain", "render", "--dem", &f, "-o", &out],
    ));
    let (tie, scale) = ([0.0, 0.0, 0.0, 7.0, 46.0, 0.0], [0.001, 0.001, 0.0]);
    let geo = [(33922, &tie[..]), (33550, &scale[..])];
    let f = w("cubits.tif", &georef_tiff(&geo, &[1024, 0, 1, 2, 2048, 0, 1, 4326, 4099, 0, 1, 9999]));
    v.push(c("GeoTIFF DEM", "vertical unit neither metre nor foot", &["terrain", "render", "--dem", &f, "-o", &out]));
    let f = w("user-defined.tif", &georef_tiff(&geo, &[1024, 0, 1, 1, 3072, 0, 1, 32767]));
    v.push(c(
        "GeoTIFF DEM",
        "user-defined CRS the coordinate library cannot resolve, reprojection asked",
        &["terrain", "render", "--dem", &f, "--crs", "EPSG:32632", "-o", &out],
    ));
    let f = w("geographic.tif", &georef_tiff(&geo, &geo_keys));
    v.push(c("--crs", "a geographic CRS", &["terrain", "render", "--dem", &f, "--crs", "EPSG:4326", "-o", &out]));
    let tie_far = [0.0, 0.0, 0.0, 7.5, 46.0, 0.0];
    let f2 = w("far-tile.tif", &georef_tiff(&[(33922, &tie_far[..]), (33550, &scale[..])], &geo_keys));
    v.push(c("DEM mosaic", "a tile that touches no other (gap)", &["terrain", "render", "--dem", &f, &f2, "-o", &out]));
    let coarse = [0.002, 0.002, 0.0];
    let tie_next = [0.0, 0.0, 0.0, 7.016, 46.0, 0.0];
    let f2 = w("coarse-tile.tif", &georef_tiff(&[(33922, &tie_next[..]), (33550, &coarse[..])], &geo_keys));
    v.push(c(
        "DEM mosaic",
        "tiles of one CRS at different resolutions",
        &["terrain", "render", "--dem", &f, &f2, "-o", &out],
    ));
    // Cloud-Optimized GeoTIFFs: overviews hitex cannot use
    let f = w("cog-rgb-overview.tif", &overview_of_another_type());
    v.push(c(
        "Cloud-Optimized GeoTIFF",
        "an overview of another sample type than the full image",
        &["terrain", "render", "--dem", &f, "--size", "64x48", "--backend", "cpu", "-o", &out],
    ));
    let f = w("cog-lost-tiles.tif", &cog_with_lost_overview_tiles());
    v.push(c(
        "Cloud-Optimized GeoTIFF",
        "the overview the view needs points past the file's end",
        &["terrain", "render", "--dem", &f, "--size", "64x48", "--backend", "cpu", "-o", &out],
    ));
    let empty = d.join("no-dems");
    std::fs::create_dir_all(&empty).unwrap();
    v.push(c(
        "DEM mosaic",
        "a folder without elevation files",
        &["terrain", "render", "--dem", &s(&empty), "-o", &out],
    ));
    // a UTM DEM near 7.7°E 46°N and web-mercator imagery 60 km east of it
    let utm_tie = [0.0, 0.0, 0.0, 400_000.0, 5_100_000.0, 0.0];
    let utm = w(
        "utm-dem.tif",
        &georef_tiff(&[(33922, &utm_tie[..]), (33550, &[30.0, 30.0, 0.0][..])], &[1024, 0, 1, 1, 3072, 0, 1, 32632]),
    );
    let merc_tie = [0.0, 0.0, 0.0, 946_000.0, 5_780_000.0, 0.0];
    let img = w(
        "elsewhere.tif",
        &georef_tiff(&[(33922, &merc_tie[..]), (33550, &[30.0, 30.0, 0.0][..])], &[1024, 0, 1, 1, 3072, 0, 1, 3857]),
    );
    v.push(c(
        "GeoTIFF imagery",
        "no overlap with the DEM after reprojection",
        &["terrain", "render", "--dem", &utm, "--image", &img, "--bands", "1,1,1", "-o", &out],
    ));
    v.push(c(
        "PNG imagery",
        "header claims 16384×16384, file of 65 bytes",
        &["terrain", "spans", "--image", &w("claim.png", &png_claim()), "--frames", "1", "-o", &out],
    ));
    let hb = w("ok.hbtf", include_bytes!("../../../fuzz/seeds/hbtf/knit-4.hbtf"));
    v.push(c(".hbtf", "valid, but beyond --max-memory 1K", &["--max-memory", "1K", "btf", "info", &hb]));
    v.push(c("--max-memory", "not a size", &["--max-memory", "lots", "btf", "info", &hb]));
    // BTFs compressed by local PCA
    let pca: &[u8] = include_bytes!("../../../fuzz/seeds/hbtf_pca/knit-4-pca.hbtf");
    let body = 56 + 4 * u32::from_le_bytes([pca[20], pca[21], pca[22], pca[23]]) as usize;
    let recrc = |b: &mut Vec<u8>| {
        let crc = hitex_io::btf_file::crc32(&b[body..]);
        b[body - 4..body].copy_from_slice(&crc.to_le_bytes());
    };
    let mut b = pca.to_vec();
    b[body..body + 2].copy_from_slice(&9u16.to_le_bytes());
    recrc(&mut b);
    v.push(c(".hbtf (local PCA)", "a texel in a cluster past the count", &["btf", "info", &w("cluster.hbtf", &b)]));
    let mut b = pca.to_vec();
    b[32..36].copy_from_slice(&3u32.to_le_bytes());
    v.push(c(".hbtf (local PCA)", "more clusters than the payload holds", &["btf", "info", &w("clusters.hbtf", &b)]));
    let f = w("cut.hbtf", &pca[..pca.len() - 10]);
    v.push(c(".hbtf (local PCA)", "truncated", &["btf", "info", &f]));
    let hp = w("ok-pca.hbtf", pca);
    v.push(c(
        ".hbtf (local PCA)",
        "valid, its reconstruction beyond --max-memory 4K",
        &["--max-memory", "4K", "btf", "info", &hp],
    ));
    v.push(c("btf render", "--pca on a compressed BTF", &["btf", "render", &hp, "--pca", "2,1", "-o", &out]));
    v.push(c(
        "STEP",
        "no B-rep faces (points only)",
        &[
            "nurbs",
            "info",
            &w("part.stp", b"ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=CARTESIAN_POINT('',(0.,0.,0.));\nENDSEC;\nEND-ISO-10303-21;\n"),
        ],
    ));
    let plate = include_str!("../../../fuzz/seeds/step/plate-with-hole.stp");
    // a well-formed file whose reading would not fit the cap
    let ok_stp = w("plate.stp", plate.as_bytes());
    v.push(c("STEP", "valid, but beyond --max-memory 16K", &["--max-memory", "16K", "nurbs", "info", &ok_stp]));
    v.push(c(
        "IGES",
        "valid, but beyond --max-memory 64K",
        &["--max-memory", "64K", "nurbs", "info", &w("teapot.igs", include_bytes!("../../hitex-io/data/teapot.igs"))],
    ));
    let many = "0.25 0.5 1\n".repeat(1000);
    v.push(c(
        "points (XYZ)",
        "valid, but beyond --max-memory 32K",
        &["--max-memory", "32K", "nurbs", "deviation", "teapot", "--points", &w("many.xyz", many.as_bytes())],
    ));
    v.push(c("STEP", "truncated inside a record", &["nurbs", "info", &w("cut.stp", &plate.as_bytes()[..400])]));
    v.push(c(
        "STEP",
        "a record with a stray character",
        &[
            "nurbs",
            "info",
            &w("stray.stp", plate.replacen("#23=LINE('',#10,#20);", "#23=LINE('',#10,@#20);", 1).as_bytes()),
        ],
    ));
    v.push(c(
        "points (XYZ)",
        "a line with two values",
        &["nurbs", "deviation", "teapot", "--points", &w("scan.xyz", b"0 0 1\n2 3\n")],
    ));
    v.push(c(
        "points (XYZ)",
        "a TIFF image given as points",
        &["nurbs", "deviation", "teapot", "--points", &w("l7.tif", b"II*\0\x08\0\0\0\x11\0\x00\x01\x03\0\x01")],
    ));
    v.push(c(
        "IGES",
        "bytes beyond ASCII in the directory",
        &[
            "nurbs",
            "info",
            &w("latin.igs", &{
                let mut t = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/teapot.igs")).unwrap();
                // the first directory line (the third: after one start and one
                // global line): a Latin-1 byte in its seventh column
                let third = t.iter().enumerate().filter(|&(_, &b)| b == b'\n').nth(1).map_or(0, |(i, _)| i + 1);
                t[third + 6] = 0xe9;
                t
            }),
        ],
    ));
    // STL references of the deviation mode
    let stl = |name: &str, bytes: &[u8]| -> Vec<String> {
        ["nurbs", "render", "teapot", "--mode", "deviation", "--reference", &w(name, bytes), "-o", &out]
            .map(String::from)
            .to_vec()
    };
    let facet = "solid s\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\nendsolid s\n";
    let bin = hitex_io::stl::to_binary_stl(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 2]);
    for (what, args) in [
        ("binary, truncated inside a triangle", stl("cut.stl", &bin[..bin.len() - 20])),
        (
            "binary, claiming 4 billion triangles",
            stl("claims.stl", &{
                let mut b = bin.clone();
                b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
                b
            }),
        ),
        (
            "ASCII, a vertex that is not a number",
            stl("word.stl", facet.replace("vertex 1 0 0", "vertex 1 oops 0").as_bytes()),
        ),
        ("ASCII, a facet of two vertices", stl("two.stl", facet.replace("   vertex 0 1 0\n", "").as_bytes())),
        ("ASCII, no facets", stl("empty.stl", b"solid s\nendsolid s\n")),
        (
            "a mesh far from the model (other units or place)",
            stl("far.stl", &hitex_io::stl::to_binary_stl(&[[[1e4, 0.0, 0.0], [1e4 + 1.0, 0.0, 0.0], [1e4, 1.0, 0.0]]])),
        ),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        v.push(c("STL (deviation reference)", what, &args));
    }
    // PLY references of the deviation mode (meshes, or points without faces)
    let ply = |name: &str, bytes: &[u8]| -> Vec<String> {
        ["nurbs", "render", "teapot", "--mode", "deviation", "--reference", &w(name, bytes), "-o", &out]
            .map(String::from)
            .to_vec()
    };
    let square = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let mut binary = square.split("end_header\n").next().unwrap_or_default().replace("ascii", "binary_little_endian");
    binary.push_str("end_header\n");
    let mut binary = binary.into_bytes();
    for x in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        binary.extend(x.to_le_bytes());
    }
    binary.push(3);
    for i in [0i32, 1, 2] {
        binary.extend(i.to_le_bytes());
    }
    for (what, args) in [
        ("binary, truncated inside a vertex", ply("cut.ply", &binary[..binary.len() - 20])),
        (
            "binary, claiming 4 billion vertices",
            ply("claims.ply", &String::from_utf8_lossy(&binary).replace("vertex 3", "vertex 4000000000").into_bytes()),
        ),
        ("ASCII, a vertex that is not a number", ply("word.ply", square.replace("1 0 0\n", "1 oops 0\n").as_bytes())),
        ("ASCII, a face index past the vertices", ply("index.ply", square.replace("3 0 1 2", "3 0 1 7").as_bytes())),
        ("ASCII, a face of two vertices", ply("two.ply", square.replace("3 0 1 2", "2 0 1").as_bytes())),
        ("a header without `end_header`", ply("open.ply", square.replace("end_header\n", "").as_bytes())),
        ("an unknown property type", ply("type.ply", square.replace("float z", "quad z").as_bytes())),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        v.push(c("PLY (deviation reference)", what, &args));
    }
    v.push(c(
        "points (JSON)",
        "a point of two coordinates",
        &["nurbs", "deviation", "teapot", "--points", &w("probe.json", b"{\"points\": [[0, 0, 1], [2, 3]]}")],
    ));
    v.push(c(
        "STEP",
        "not a STEP file (.stp name)",
        &["nurbs", "info", &w("mesh.stp", b"solid cube\nendsolid cube\n")],
    ));
    v.push(c(
        "STEP",
        "every face on a surface not read yet",
        &[
            "nurbs",
            "render",
            &w(
                "ext.stp",
                plate
                    .replacen("#5=PLANE('',#4);", "#5=OFFSET_SURFACE('',#51,2.,.F.);\n#51=PLANE('',#4);", 1)
                    .as_bytes(),
            ),
            "-o",
            &out,
        ],
    ));
    // trim curves: the arc-holes fixture with one curve broken (same record length)
    let holes =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../hitex-io/data/arc-holes.igs")).unwrap();
    let f = w(
        "arc-at-centre.igs",
        holes.replacen("100,0.,0.3,0.5,0.45,0.5,0.45,0.5;", "100,0.,0.3,0.5,0.30,0.5,0.30,0.5;", 1).as_bytes(),
    );
    v.push(c("IGES", "trim arc (100) of radius zero", &["nurbs", "render", &f, "--size", "32x24", "-o", &out]));
    let f = w(
        "rotated-conic.igs",
        holes.replacen("104,0.0625,0.,0.0144,0.,0.,-0.0009,", "104,0.0625,1.,0.0144,0.,0.,-0.0009,", 1).as_bytes(),
    );
    v.push(c(
        "IGES",
        "trim conic (104) off standard position",
        &["nurbs", "render", &f, "--size", "32x24", "-o", &out],
    ));
    // the base surface's colour number pointing at the arc (entry 2), not at a colour definition (314)
    let coloured: Vec<String> = holes
        .lines()
        .map(|l| if l.ends_with("D      2") { format!("{}{:>8}{}", &l[..16], -3, &l[24..]) } else { l.to_string() })
        .collect();
    let f = w("colour-pointer.igs", (coloured.join("\n") + "\n").as_bytes());
    v.push(c(
        "IGES",
        "colour number pointing at no colour definition (314)",
        &["nurbs", "render", &f, "--size", "32x24", "-o", &out],
    ));
    // a parametric spline surface (114) whose u breakpoints repeat (same record length)
    let spline = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/iges/spline-surface-114.igs"),
    )
    .unwrap();
    let f = w("spline-breaks.igs", spline.replacen("114,3,1,2,1,0.,1.,2.,", "114,3,1,2,1,0.,1.,1.,", 1).as_bytes());
    v.push(c("IGES", "parametric spline surface (114) with breakpoints that do not rise", &["nurbs", "info", &f]));
    // a surface of revolution (120) whose generatrix pointer names the matrix (124) instead of a curve
    let swept =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/iges/swept-surfaces.igs"))
            .unwrap();
    let f = w("revolved-matrix.igs", swept.replacen("120,1,3,", "120,1,9,", 1).as_bytes());
    v.push(c(
        "IGES",
        "surface of revolution (120) of an entity that is not a curve",
        &["nurbs", "render", &f, "--size", "32x24", "-o", &out],
    ));
    v.push(c("IGES", "no such file", &["nurbs", "info", &s(&d.join("gone.igs"))]));
    v.push(c("GST store", "no metadata.json", &["terrain", "fly", &s(d), "-o", &s(&d.join("frames"))]));
    let store = d.join("store");
    std::fs::create_dir_all(&store).unwrap();
    std::fs::write(store.join("metadata.json"), r#"{"format": "hitex-gst", "version": 7}"#).unwrap();
    v.push(c(
        "GST store",
        "metadata of another format version",
        &["terrain", "fly", &s(&store), "-o", &s(&d.join("frames"))],
    ));
    v.push(c("terrain build", "no imagery given", &["terrain", "build", "-o", &s(&d.join("st"))]));
    let flat = d.join("flat-store");
    assert!(hitex(&["terrain", "build", "--procedural", "300x300", "-o", &s(&flat)]).status.success());
    v.push(c(
        "terrain fly",
        "--ground relief, the store holds no DEM",
        &["terrain", "fly", &s(&flat), "--ground", "relief", "-o", &s(&d.join("frames"))],
    ));
    let olinda = d.join("olinda-store");
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/olinda/");
    let (dem, image) = (format!("{data}olinda_dem_utm25s.tif"), format!("{data}L7_ETMs.tif"));
    assert!(hitex(&["terrain", "build", "--image", &image, "--dem", &dem, "-o", &s(&olinda)]).status.success());
    // MBTiles: one SQLite file of web-mercator tiles
    let mb = d.join("olinda.mbtiles");
    assert!(hitex(&["terrain", "build", "--image", &image, "--dem", &dem, "-o", &s(&mb)]).status.success());
    let text_mb = w("notes.mbtiles", b"my notes, not tiles");
    v.push(c("MBTiles store", "not an SQLite file", &["terrain", "fly", &text_mb, "-o", &s(&d.join("frames"))]));
    let edited = |name: &str, sql: &str| -> String {
        let p = d.join(name);
        std::fs::copy(&mb, &p).unwrap();
        rusqlite::Connection::open(&p).unwrap().execute_batch(sql).unwrap();
        s(&p)
    };
    // another tool's files (no hitex description) hitex cannot fly over
    let foreign = "DELETE FROM metadata WHERE name = 'hitex'; DROP TABLE hitex_files;";
    for (name, sql, what) in [
        ("vector.mbtiles", "UPDATE metadata SET value = 'pbf' WHERE name = 'format';", "vector tiles (format pbf)"),
        ("webp.mbtiles", "UPDATE metadata SET value = 'webp' WHERE name = 'format';", "WebP tiles"),
        (
            "bounds.mbtiles",
            "UPDATE metadata SET value = '-35,-8' WHERE name = 'bounds';",
            "a bounds row of two numbers",
        ),
        (
            "wide.mbtiles",
            "UPDATE metadata SET value = '-40,-12,-30,-2' WHERE name = 'bounds'; DELETE FROM tiles WHERE zoom_level < 13;",
            "bounds of 10° × 10° over its zoom-13 tiles only",
        ),
    ] {
        let p = edited(name, &format!("{foreign} {sql}"));
        v.push(c("MBTiles by another tool", what, &["terrain", "fly", &p, "-o", &s(&d.join("frames"))]));
    }
    let holes = edited("holes.mbtiles", "DELETE FROM tiles WHERE zoom_level = 11;");
    v.push(c("MBTiles store", "its level-0 tile missing", &["terrain", "fly", &holes, "-o", &s(&d.join("frames"))]));
    let big = edited("big.mbtiles", "UPDATE tiles SET tile_data = zeroblob(5000000) WHERE zoom_level = 11;");
    v.push(c("MBTiles store", "a tile of 5 MB", &["terrain", "fly", &big, "-o", &s(&d.join("frames"))]));
    v.push(c(
        "terrain build",
        "--format mbtiles of procedural imagery (no CRS)",
        &["terrain", "build", "--procedural", "300x300", "-o", &s(&d.join("p.mbtiles"))],
    ));
    v.push(c(
        "terrain build",
        "-o names a file that is not an MBTiles file",
        &["terrain", "build", "--image", &image, "-o", &text_mb],
    ));
    v.push(c(
        "terrain pack",
        "a local (not web-mercator) store",
        &["terrain", "pack", &s(&olinda), "-o", &s(&d.join("x.mbtiles"))],
    ));
    let world = w("ortho.png", &std::fs::read(image_png_for_catalogue(d)).unwrap());
    std::fs::write(d.join("ortho.pgw"), "28.5\n0.2\n0\n-28.5\n288790\n9120740\n").unwrap();
    v.push(c(
        "world file",
        "rotation terms (a rotated raster)",
        &["terrain", "render", "--dem", &dem, "--image", &world, "-o", &out],
    ));
    v.push(c(
        "terrain fly",
        "camera below the exaggerated relief",
        &["terrain", "fly", &s(&olinda), "--altitude", "1", "--exaggeration", "50", "-o", &s(&d.join("frames"))],
    ));
    v.push(c(
        "output image",
        "a file on its path where a folder must be",
        &["btf", "render", "knit", "--size", "8x8", "-o", &s(&d.join("ok.hbtf/x.png")), "--backend", "cpu"],
    ));
    v.push(c(
        "output image",
        "an extension that names no image format",
        &["btf", "render", "knit", "--size", "8x8", "-o", &s(&d.join("x.txt")), "--backend", "cpu"],
    ));
    v.push(c("btf render", "--repeats 0", &["btf", "render", "knit", "--repeats", "0", "-o", &out]));
    v.push(c("btf render", "--pca 0,4 (no cluster)", &["btf", "render", "knit", "--pca", "0,4", "-o", &out]));
    v.push(c("btf render", "--pca 8 (not CLUSTERS,COMPONENTS)", &["btf", "render", "knit", "--pca", "8", "-o", &out]));
    v.push(c(
        "btf render",
        "--pca 1,16 (too many components)",
        &["btf", "render", "knit", "--pca", "1,16", "-o", &out],
    ));
    v.push(c("btf render", "--pca with --bc1", &["btf", "render", "knit", "--pca", "1,8", "--bc1", "-o", &out]));
    let nonempty = d.join("nonempty");
    std::fs::create_dir_all(&nonempty).unwrap();
    std::fs::write(nonempty.join("keep.txt"), b"mine").unwrap();
    v.push(c("btf export", "into a folder that is not empty", &["btf", "export", &hb, "-o", &s(&nonempty)]));
    v.push(c(
        "terrain build",
        "--procedural 10000000x10000000 (beyond --max-maps)",
        &["terrain", "build", "--procedural", "10000000x10000000", "-o", &s(&d.join("huge"))],
    ));
    v.push(c("terrain fly", "--frames 0", &["terrain", "fly", &s(&flat), "--frames", "0", "-o", &s(&d.join("f0"))]));
    v.push(c("terrain fly", "--budget 0", &["terrain", "fly", &s(&flat), "--budget", "0", "-o", &s(&d.join("f0"))]));
    let outside = w("outside.toml", b"[[key]]\nt = 0\nx = 1.5\ny = 0.5\naltitude = 100\npitch = 30\nheading = 0\n");
    v.push(c(
        "flight path",
        "a key outside the store",
        &["terrain", "fly", &s(&flat), "--path", &outside, "-o", &s(&d.join("f0"))],
    ));
    // faults of the disk and the GPU
    let scene = w("scene.toml", hitex_core::scene::SHOWCASE_TOML.as_bytes());
    let render = |out: &str| -> Vec<String> {
        ["render", &scene, "-o", out, "--size", "64x48", "--backend", "cpu"].iter().map(|a| a.to_string()).collect()
    };
    if let Some(full) = Tmpfs::mount_at(&d.join("full"), 64) {
        full.fill();
        mounts.push(full);
    }
    let mut k = c("output image", "disk full", &[]);
    k.args = render(&s(&d.join("full/out.png")));
    k.needs = Needs::Mount;
    v.push(k);
    let mut k =
        c(".hbtf output", "disk full", &["btf", "synth", "knit", "--size", "4", "-o", &s(&d.join("full/k.hbtf"))]);
    k.needs = Needs::Mount;
    v.push(k);
    if let Some(ro) = Tmpfs::mount_at(&d.join("ro"), 64) {
        ro.read_only();
        mounts.push(ro);
    }
    let mut k = c("output image", "read-only folder", &[]);
    k.args = render(&s(&d.join("ro/out.png")));
    k.needs = Needs::Mount;
    v.push(k);
    let mut k = c("GPU", "no adapter, --backend gpu", &[]);
    k.args = render(&s(&d.join("gpu.png")));
    k.args.pop();
    k.args.push("gpu".into());
    k.env = vec![("WGPU_BACKEND", "metal")];
    v.push(k);
    let mut k = c("GPU", "device lost, --backend gpu", &[]);
    k.args = render(&s(&d.join("gpu.png")));
    k.args.pop();
    k.args.push("gpu".into());
    k.env = vec![("HITEX_GPU_FAULT", "device-lost")];
    k.needs = Needs::Gpu;
    v.push(k);
    v
}

/// A 32×32 float DEM in UTM 32N followed by a reduced-resolution RGB image.
fn overview_of_another_type() -> Vec<u8> {
    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(32, 32).unwrap();
    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[30.0, 30.0, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 4e5, 5.1e6, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &[1u16, 1, 0, 1, 3072, 0, 1, 32632][..]).unwrap();
    let hill: Vec<f32> = (0..32 * 32).map(|k| 100.0 + (k % 32) as f32 * 3.0 + (k / 32) as f32).collect();
    img.write_data(&hill).unwrap();
    let mut img = enc.new_image::<colortype::RGB32Float>(16, 16).unwrap();
    img.encoder().write_tag(Tag::NewSubfileType, 1u32).unwrap();
    img.write_data(&[0.5f32; 16 * 16 * 3]).unwrap();
    buf.into_inner()
}

/// A COG of 1100×1000 posts (more than a 64×48 view meshes) whose first
/// overview's tile offsets point past the file's end.
fn cog_with_lost_overview_tiles() -> Vec<u8> {
    let (w, h) = (1100u32, 1000u32);
    let r = hitex_io::geotiff::GeoRaster {
        width: w,
        height: h,
        bands: 1,
        data: (0..w * h).map(|k| 100.0 + (k % w) as f32 * 0.1 + (k / w) as f32 * 0.05).collect(),
        origin: [400_000.0, 5_110_000.0],
        pixel: [10.0, 10.0],
        nodata: None,
        epsg: Some(32632),
        projection: None,
        citation: None,
        proj4: None,
    };
    let utm = hitex_io::crs::Crs::from_epsg(32632).unwrap();
    let mut b = hitex_io::geotiff::cog_bytes(&r, &utm, 256).unwrap();
    let u16_at = |b: &[u8], at: usize| u16::from_le_bytes([b[at], b[at + 1]]) as usize;
    let u32_at = |b: &[u8], at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize;
    // the second IFD (the first overview), found from the first's next pointer
    let ifd1 = u32_at(&b, 10 + 12 * u16_at(&b, 8));
    for e in 0..u16_at(&b, ifd1) {
        let at = ifd1 + 2 + 12 * e;
        if u16_at(&b, at) == 324 {
            let (n, offsets) = (u32_at(&b, at + 4), u32_at(&b, at + 8));
            for k in 0..n {
                b[offsets + 4 * k..offsets + 4 * k + 4].copy_from_slice(&0x7fff_0000u32.to_le_bytes());
            }
        }
    }
    b
}

/// A little-endian TIFF whose one IFD declares a 16384×16384 float raster
/// backed by a 4-byte strip.
/// A 16×16 int16 GeoTIFF with the given georeferencing tags (f64 values)
/// and GeoKeys (four numbers a key).
fn georef_tiff(tags: &[(u16, &[f64])], keys: &[u16]) -> Vec<u8> {
    use tiff::encoder::{TiffEncoder, colortype::GrayI16};
    use tiff::tags::Tag;
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<GrayI16>(16, 16).unwrap();
    for (tag, v) in tags {
        img.encoder().write_tag(Tag::Unknown(*tag), *v).unwrap();
    }
    let mut dir = vec![1u16, 1, 0, (keys.len() / 4) as u16];
    dir.extend_from_slice(keys);
    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &dir[..]).unwrap();
    img.write_data(&[100i16; 256]).unwrap();
    buf.into_inner()
}

fn tiff_claim() -> Vec<u8> {
    let entries: [(u16, u16, u32); 10] = [
        (256, 4, 16384), // ImageWidth, LONG
        (257, 4, 16384), // ImageLength
        (258, 3, 32),    // BitsPerSample, SHORT
        (259, 3, 1),     // Compression: none
        (262, 3, 1),     // Photometric: black is zero
        (273, 4, 8),     // StripOffsets
        (277, 3, 1),     // SamplesPerPixel
        (278, 4, 16384), // RowsPerStrip
        (279, 4, 4),     // StripByteCounts
        (339, 3, 3),     // SampleFormat: IEEE float
    ];
    let mut b = b"II*\x00".to_vec();
    b.extend_from_slice(&12u32.to_le_bytes());
    b.extend_from_slice(&[0; 4]); // the "strip"
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, val) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        if ty == 3 {
            b.extend_from_slice(&(val as u16).to_le_bytes());
            b.extend_from_slice(&[0, 0]);
        } else {
            b.extend_from_slice(&val.to_le_bytes());
        }
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b
}

/// A PNG whose header declares 16384×16384 RGBA over one empty data chunk.
fn png_claim() -> Vec<u8> {
    let chunk = |out: &mut Vec<u8>, ty: &[u8], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend_from_slice(ty);
        out.extend_from_slice(data);
        let crc = hitex_io::btf_file::crc32(&out[start..]);
        out.extend_from_slice(&crc.to_be_bytes());
    };
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&16384u32.to_be_bytes());
    ihdr.extend_from_slice(&16384u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    chunk(&mut b, b"IHDR", &ihdr);
    chunk(&mut b, b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(&mut b, b"IEND", &[]);
    b
}

#[test]
fn the_catalogue_matches_the_behaviour() {
    let d = tmp("catalogue");
    let prefix = s(&d);
    let mut table = String::from(
        "# Bad input: what hitex does with it\n\n\
         Generated by `crates/hitex-cli/tests/catalogue.rs` from the cases it runs (`HITEX_BLESS=1 cargo test -p hitex-cli --test catalogue` rewrites this file; the test fails when it and the behaviour differ). Paths are shown relative to the test's folder.\n\n\
         | input | what is wrong | exit code | what the user sees |\n|---|---|---|---|\n",
    );
    let mut mounts = Vec::new();
    let all = cases(&d, &mut mounts);
    let gpu = !String::from_utf8_lossy(&hitex(&["info"]).stdout).contains("no GPU adapter found");
    let mut skipped = Vec::new();
    let mut rows = Vec::new();
    for case in all {
        if (case.needs == Needs::Mount && mounts.len() < 2) || (case.needs == Needs::Gpu && !gpu) {
            skipped.push(format!("{} / {}", case.input, case.wrong));
            continue;
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_hitex"))
            .args(&case.args)
            .envs(case.env.iter().copied())
            .output()
            .unwrap_or_else(|e| panic!("cannot run hitex: {e}"));
        let code = o.status.code().unwrap_or(-1);
        // clap's own usage errors start with "error:"; ours with "hitex:"
        let mut lines = error_lines(&o);
        if lines.is_empty() {
            lines = String::from_utf8_lossy(&o.stderr)
                .lines()
                .filter(|l| l.starts_with("error:"))
                .map(str::to_string)
                .collect();
        }
        assert_eq!(lines.len(), 1, "{} / {}: expected one error line, got {lines:?}", case.input, case.wrong);
        // an error, or a warning for what is read without the bad part
        assert!(
            code == 1 || code == 2 || (code == 0 && lines[0].starts_with("hitex: warning:")),
            "{} / {}: exit {code}",
            case.input,
            case.wrong
        );
        let line = lines[0].replace(&format!("{prefix}/"), "").replace('|', "\\|");
        let env: Vec<String> = case.env.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let env = if env.is_empty() { String::new() } else { format!(" (`{}`)", env.join(" ")) };
        let row = format!("| {} | {}{env} | {code} | `{line}` |\n", case.input, case.wrong);
        table += &row;
        rows.push(row);
    }
    drop(mounts);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/bad-input.md");
    if std::env::var("HITEX_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &table).unwrap();
        return;
    }
    let have = std::fs::read_to_string(&path).unwrap_or_default();
    if !skipped.is_empty() {
        // without root or a GPU some rows cannot be made: check the others, line by line
        common::say_skipped(&format!("SKIPPED catalogue rows (no tmpfs mount or no GPU adapter): {skipped:?}"));
        if std::env::var("HITEX_REQUIRE_FAULTS").is_ok_and(|v| v == "1") {
            panic!("catalogue rows skipped with HITEX_REQUIRE_FAULTS=1: {skipped:?}");
        }
        for row in &rows {
            assert!(have.contains(row.as_str()), "docs/bad-input.md lacks or differs in {row}");
        }
        return;
    }
    assert_eq!(
        have, table,
        "docs/bad-input.md differs from the behaviour; rerun with HITEX_BLESS=1 and review the diff"
    );
}

/// A small PNG written into `d` for the world-file case.
fn image_png_for_catalogue(d: &Path) -> std::path::PathBuf {
    let p = d.join("ortho-source.png");
    hitex_io::save_png(&p, 2, 2, &[200; 16]).unwrap();
    p
}
