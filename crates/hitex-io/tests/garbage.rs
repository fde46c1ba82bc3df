//! Every parser against hostile input: random bytes, truncations and single-byte
//! corruptions of real files. The contract is an `Err` with a message (or a
//! valid result), never a panic, hang or runaway allocation.

use proptest::prelude::*;

const TEAPOT: &str = include_str!("../data/teapot.igs");
const HOLED: &str = include_str!("../data/holed-square.igs");
const SCENE: &str = hitex_core::scene::SHOWCASE_TOML;
const STEP_PART: &str = include_str!("../data/cad/face_recognition_sample_part.stp");
const STEP_PLATE: &str = include_str!("../../../fuzz/seeds/step/plate-with-hole.stp");

fn holed() -> Vec<hitex_io::IgesSurface> {
    match hitex_io::iges::parse_iges(HOLED, "holed") {
        Ok(m) => m.surfaces,
        Err(e) => panic!("fixture: {e}"),
    }
}

/// Runs every text parser on `text`; only panics matter.
fn all_parsers(text: &str) {
    let _ = hitex_io::iges::parse_iges(text, "fuzz.igs");
    let _ = hitex_io::obj_freeform::parse_obj_freeform(text);
    let _ = hitex_io::nurbs_json::parse_nurbs_json(text);
    let _ = hitex_io::step::parse_step(text.as_bytes(), "fuzz.stp", &hitex_io::StepOptions::default());
    if let Ok(d) = hitex_core::scene::SceneDesc::from_toml(text) {
        let _ = d.resolve(&hitex_core::scene::NoFiles);
    }
}

fn corrupt(base: &str, pos: usize, byte: u8, cut: usize) -> String {
    let mut b = base.as_bytes().to_vec();
    let n = b.len();
    b[pos % n] = byte;
    b.truncate(cut % (n + 1));
    String::from_utf8_lossy(&b).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, .. ProptestConfig::default() })]

    #[test]
    fn random_text_never_panics(s in "\\PC{0,400}") {
        all_parsers(&s);
    }

    #[test]
    fn corrupted_real_files_never_panic(pos: usize, byte: u8, cut: usize, which in 0usize..6) {
        let base = match which {
            0 => TEAPOT.to_string(),
            1 => HOLED.to_string(),
            4 => STEP_PART.to_string(),
            5 => STEP_PLATE.to_string(),
            2 => hitex_io::obj_freeform::to_obj_freeform(&holed()),
            _ => hitex_io::nurbs_json::to_nurbs_json(&holed()),
        };
        all_parsers(&corrupt(&base, pos, byte, cut));
    }

    #[test]
    fn corrupted_scenes_never_panic(pos: usize, byte in 32u8..127, cut: usize) {
        all_parsers(&corrupt(SCENE, pos, byte, cut));
    }

    #[test]
    fn numbers_swapped_for_extremes_never_panic(
        k in 0usize..400,
        v in prop::sample::select(vec!["nan", "inf", "-1", "0", "1e308", "99999999", "-99999999", "1e-320", "x"]),
    ) {
        // replace the k-th number of a real record by an extreme value
        for base in [HOLED, TEAPOT, STEP_PLATE, STEP_PART] {
            let mut count = 0;
            let out: Vec<String> = base
                .split(',')
                .map(|tok| {
                    count += 1;
                    if count == k + 2 && tok.trim().parse::<f64>().is_ok() { v.to_string() } else { tok.to_string() }
                })
                .collect();
            all_parsers(&out.join(","));
        }
    }
}

#[test]
fn garbage_image_files_are_errors_not_panics() {
    let dir = std::env::temp_dir().join(format!("hitex-garbage-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ok = dir.join("ok.png");
    hitex_io::save_png(&ok, 16, 16, &[128; 16 * 16 * 4]).unwrap();
    let png = std::fs::read(&ok).unwrap();
    let bad = dir.join("bad.png");
    for k in 0..png.len() {
        let mut b = png.clone();
        b[k] ^= 0x5a;
        std::fs::write(&bad, &b).unwrap();
        let _ = hitex_io::load_image(&bad, hitex_core::texture::ColorSpace::Srgb);
    }
    let cut = dir.join("cut.png");
    for n in [0, 8, 20, 33, png.len() / 2] {
        std::fs::write(&cut, &png[..n]).unwrap();
        assert!(hitex_io::load_image(&cut, hitex_core::texture::ColorSpace::Srgb).is_err(), "{n} bytes accepted");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
