use super::*;
use crate::terrain::FlyCamera;
use std::collections::HashMap;
use std::sync::Arc;

/// A page table of 4 levels, 3×3 maps a level, some slots empty, some
/// served by a coarser map, texels (alpha too) from a hash.
fn pages() -> FlyPages {
    let (levels, per) = (4u32, 3u32);
    let mut maps = HashMap::new();
    let mut slots = Vec::new();
    let origins: Vec<[i32; 2]> = (0..levels).map(|z| [(1i32 << z) / 2 - 1, (1i32 << z) / 2 - 1]).collect();
    for z in 0..levels {
        for k in 0..(per * per) as i32 {
            let (x, y) = (origins[z as usize][0] + k % per as i32, origins[z as usize][1] + k / per as i32);
            let h = (x * 73 + y * 151 + z as i32 * 29).rem_euclid(7);
            if x < 0 || y < 0 || h == 0 {
                slots.push(None);
                continue;
            }
            // every third map stands in for itself one level coarser, as while it loads
            let key = if h == 3 && z > 0 {
                MapKey { z: z - 1, x: x as u32 / 2, y: y as u32 / 2 }
            } else {
                MapKey { z, x: x as u32, y: y as u32 }
            };
            maps.entry(key).or_insert_with(|| {
                let mut t = vec![0u8; (MAP * MAP * 4) as usize];
                for (i, b) in t.iter_mut().enumerate() {
                    let v = (i as u32 ^ (key.x * 977) ^ (key.y * 4099) ^ (key.z * 131)).wrapping_mul(2_654_435_761);
                    *b = (v >> 24) as u8;
                }
                Arc::new(t)
            });
            slots.push(Some(key));
        }
    }
    FlyPages { levels, per_side: per, origins, slots, maps }
}

#[test]
fn page_tables_past_31_levels_are_refused() {
    let levels = 32;
    let pages = FlyPages {
        levels,
        per_side: 1,
        origins: vec![[0, 0]; levels as usize],
        slots: vec![None; levels as usize],
        maps: Default::default(),
    };
    let cam = FlyCamera::new(100.0, 100.0, 50.0, 40.0, 0.0, 50.0);
    let u = FlyUniform::new(&cam, 16, 16, levels, 1);
    let e = render_fly(&u, &pages, FlyGround::Flat).err().map(|e| e.to_string());
    assert_eq!(e.as_deref(), Some("the page table has 32 levels; at most 31"));
}

/// The trilinear reads as AVX-512 gathers return the lane loop's bits,
/// on views whose blocks read one map, several maps, empty slots and maps
/// standing in for a finer level.
#[test]
fn trilinear_gathers_read_the_lane_loops_bits() {
    if !super::super::simd::SimdLevel::Avx512.available() {
        // past the harness's capture, so that the skip shows in every log
        let _ = std::io::Write::write_all(
            &mut std::io::stderr(),
            b"SKIPPED: trilinear_gathers_read_the_lane_loops_bits: this processor lacks AVX-512\n",
        );
        assert!(!std::env::var("HITEX_REQUIRE_AVX512").is_ok_and(|v| v == "1"), "HITEX_REQUIRE_AVX512=1");
        return;
    }
    let pages = pages();
    for &(x, y, alt, pitch, heading) in
        &[(1024.0, 1024.0, 300.0, 20.0, 20.0), (700.0, 1500.0, 80.0, 60.0, 300.0), (1200.0, 900.0, 900.0, 80.0, 135.0)]
    {
        let cam = FlyCamera::new(x, y, alt, pitch, heading, 50.0);
        let (w, h) = (96u32, 64u32);
        let u = FlyUniform::new(&cam, w, h, pages.levels, pages.per_side);
        let mut wide = bind(&u, &pages, None).unwrap();
        wide.wide = true;
        let mut lanes = bind(&u, &pages, None).unwrap();
        lanes.wide = false;
        for py in 0..h {
            for x0 in (0..w).step_by(LANES) {
                let (a, b) = (wide.shade_flat_lanes(x0, py), lanes.shade_flat_lanes(x0, py));
                for c in 0..3 {
                    for i in 0..LANES {
                        assert_eq!(a[c][i].to_bits(), b[c][i].to_bits(), "({x0}, {py}) lane {i}");
                    }
                }
            }
        }
    }
}

#[test]
fn span_lanes_equal_the_span_program() {
    let pages = pages();
    let views = [
        (1024.0, 1024.0, 300.0, 20.0, 20.0),
        (700.0, 1500.0, 80.0, 60.0, 300.0),
        (1200.0, 900.0, 900.0, 80.0, 135.0),
        // high enough that spans read virtual levels beyond the coarsest
        (1024.0, 1024.0, 3000.0, 10.0, 10.0),
    ];
    for sampler in [FlySampler::Span3, FlySampler::Span4, FlySampler::Bicubic] {
        for (n, &(x, y, alt, pitch, heading)) in views.iter().enumerate() {
            let cam = FlyCamera::new(x, y, alt, pitch, heading, 50.0);
            // odd sizes: the last span column and row reach past the frame
            let (w, h) = (101u32, 61u32);
            let u = FlyUniform::new(&cam, w, h, pages.levels, pages.per_side).with_sampler(sampler);
            let prog = bind(&u, &pages, None).unwrap();
            let mut seen = std::collections::HashSet::new();
            for py in (0..h).step_by(2) {
                for x0 in (0..w).step_by(8) {
                    let lanes = prog.shade_spans_lanes(x0, py);
                    for s in 0..4u32 {
                        let want = prog.shade_flat_span(x0 + 2 * s, py, None);
                        for q in 0..4usize {
                            let i = 4 * s as usize + q;
                            let got = [lanes[0][i], lanes[1][i], lanes[2][i]];
                            assert_eq!(
                                got.map(f32::to_bits),
                                want[q].map(f32::to_bits),
                                "{} view {n}, span ({}, {py}) pixel {q}",
                                sampler.name(),
                                x0 + 2 * s
                            );
                            seen.insert(want[q].map(f32::to_bits));
                        }
                    }
                }
            }
            assert!(seen.len() > 100, "{} view {n}: {} colours", sampler.name(), seen.len());
            if n == 3 {
                // the far spans of this view read levels past the coarsest (virtual)
                let mut m = BankModel::new(SpanScheme::Banks4x4);
                for x0 in (0..w).step_by(2) {
                    prog.shade_flat_span(x0, 0, Some(&mut m));
                }
                assert!(m.mean_level() > (pages.levels - 1) as f64, "mean level {}", m.mean_level());
            }
        }
    }
}

#[test]
fn flat_lanes_equal_the_per_pixel_program() {
    let pages = pages();
    // looking down, across, at the horizon (sky lanes), from low and high,
    // a width that ends inside a block
    let views =
        [(1024.0, 1024.0, 300.0, 20.0, 20.0), (700.0, 1500.0, 80.0, 60.0, 300.0), (1200.0, 900.0, 900.0, 80.0, 135.0)];
    for (n, &(x, y, alt, pitch, heading)) in views.iter().enumerate() {
        let cam = FlyCamera::new(x, y, alt, pitch, heading, 50.0);
        let (w, h) = (100u32, 60u32);
        let u = FlyUniform::new(&cam, w, h, pages.levels, pages.per_side);
        let prog = bind(&u, &pages, None).unwrap();
        let mut skies = 0;
        let mut seen = std::collections::HashSet::new();
        for py in 0..h {
            for x0 in (0..w).step_by(LANES) {
                let lanes = prog.shade_flat_lanes(x0, py);
                for i in 0..LANES.min((w - x0) as usize) {
                    let want = prog.shade_flat(x0 + i as u32, py);
                    let got = [lanes[0][i], lanes[1][i], lanes[2][i]];
                    assert_eq!(
                        got.map(f32::to_bits),
                        want.map(f32::to_bits),
                        "view {n}, pixel ({}, {py})",
                        x0 + i as u32
                    );
                    skies += usize::from(want == sky(py as f32 + 0.5, h as f32));
                    seen.insert(want.map(f32::to_bits));
                }
            }
        }
        assert!(seen.len() > 200, "view {n}: imagery, not a flat colour ({} colours)", seen.len());
        if n == 2 {
            assert!(skies > 0 && skies < (w * h) as usize, "view 2 shows sky and ground ({skies} sky pixels)");
        }
    }
}
