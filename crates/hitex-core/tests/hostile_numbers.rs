//! The math that takes user numbers, fed every class of f32/f64 (NaN, ±inf,
//! subnormals, ±0, huge and tiny magnitudes): it returns a clear error or a
//! finite, in-range result; never a panic and never a NaN that would reach a
//! pixel. Where a value is clamped, the clamp is the documented one.

use glam::{Vec2, Vec3};
use hitex_core::btf::frames::angles;
use hitex_core::nurbs::NurbsSurface;
use hitex_core::scene::Camera;
use hitex_core::texture::sampler::{Filter, Jacobian, LevelRule, SamplerOptions, Wrap, level_of_detail, sample};
use hitex_core::texture::{ColorSpace, Image, MipPyramid};
use proptest::prelude::*;

/// Any f32 at all, with the special values well represented.
fn wild32() -> impl Strategy<Value = f32> {
    prop_oneof![
        proptest::num::f32::ANY,
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        Just(-0.0f32),
        -4.0f32..4.0,
    ]
}

fn wild64() -> impl Strategy<Value = f64> {
    prop_oneof![
        proptest::num::f64::ANY,
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::MAX),
        Just(1e-300),
        Just(1e300),
        -4.0f64..4.0,
    ]
}

fn wild_vec3() -> impl Strategy<Value = Vec3> {
    (wild32(), wild32(), wild32()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn checker() -> MipPyramid {
    let img =
        Image::from_fn(
            8,
            4,
            ColorSpace::Srgb,
            |x, y| if (x + y) % 2 == 0 { [250, 10, 30, 255] } else { [5, 200, 90, 128] },
        );
    MipPyramid::build(img.unwrap_or_else(|e| panic!("{e}")))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, .. ProptestConfig::default() })]

    #[test]
    fn sampler_coordinates_of_any_size(u in wild32(), v in wild32(), j in (wild32(), wild32(), wild32(), wild32()),
                                       bias in wild32(), f in 0usize..3, w in 0usize..3, rule: bool) {
        let pyr = checker();
        let opts = SamplerOptions {
            filter: [Filter::Nearest, Filter::Bilinear, Filter::Trilinear][f],
            wrap: [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror][w],
            level_rule: if rule { LevelRule::MaxPartial } else { LevelRule::VulkanRho },
            lod_bias: bias,
        };
        let jac = Jacobian { du_dx: j.0, dv_dx: j.1, du_dy: j.2, dv_dy: j.3 };
        let c = sample(&pyr, &opts, Vec2::new(u, v), jac);
        prop_assert!(c.is_finite(), "{c:?} at ({u}, {v}) with {jac:?}, bias {bias}");
        prop_assert!(c.min_element() >= 0.0 && c.max_element() <= 1.0 + 1e-6, "{c:?}");
        let l = level_of_detail(opts.level_rule, jac, 8, 4);
        prop_assert!(!l.is_nan(), "λ is NaN for {jac:?}");
    }

    #[test]
    fn cameras_from_any_numbers(p in wild_vec3(), t in wild_vec3(), up in wild_vec3(),
                                fov in wild32(), near in wild32(), far in wild32(), angle in wild32()) {
        if let Ok(c) = Camera::new(p, t, up, fov, near, far) {
            let m = c.view_proj(16.0 / 9.0);
            prop_assert!(m.is_finite(), "{c:?} gives {m:?}");
            if angle.is_finite() && angle.abs() < 1e4 {
                let o = c.orbit(angle);
                prop_assert!(o.validate().is_ok() || !o.position.is_finite(), "orbit broke {c:?}");
            }
        }
    }

    #[test]
    fn btf_angles_from_any_frame(p in wild_vec3(), n in wild_vec3(), u in wild_vec3(), v in wild_vec3(), pc in wild_vec3()) {
        let (theta, phi) = angles(p, n, u, v, pc);
        prop_assert!(theta.is_finite() && (0.0..=std::f32::consts::PI + 1e-6).contains(&theta), "θ {theta}");
        prop_assert!(phi.is_finite() && (0.0..=std::f32::consts::TAU).contains(&phi), "φ {phi}");
    }

    #[test]
    fn nurbs_from_any_knots_and_weights(
        p in 1usize..=4, extra in 0usize..4,
        knots in proptest::collection::vec(wild64(), 1..12),
        coords in proptest::collection::vec(wild64(), 4..8),
        weights in proptest::collection::vec(wild64(), 1..6),
        u in wild64(), v in wild64(),
    ) {
        let n = p + 1 + extra;
        // knots: the drawn values, sorted when they are comparable, padded to the needed count
        let mut k: Vec<f64> = (0..n + p + 1).map(|i| knots[i % knots.len()]).collect();
        if k.iter().all(|x| !x.is_nan()) && (n + extra) % 3 != 0 {
            k.sort_by(f64::total_cmp);
        }
        let pts: Vec<[f64; 4]> = (0..n * (p + 1))
            .map(|i| [coords[i % coords.len()] * i as f64, coords[(i + 1) % coords.len()], coords[(i + 2) % coords.len()],
                      weights[i % weights.len()]])
            .collect();
        let clamped: Vec<f64> = [vec![0.0; p + 1], vec![1.0; p + 1]].concat();
        if let Ok(s) = NurbsSurface::new(p, p, n, p + 1, k, clamped, pts) {
            let q = s.point(u, v);
            let nn = s.normal(u, v);
            prop_assert!(nn.iter().all(|x| x.is_finite()), "normal {nn:?}");
            prop_assert!(q.iter().all(|x| x.is_finite()), "point {q:?} at ({u}, {v})");
        }
    }

    #[test]
    fn active_area_from_any_view(fov in wild64(), px in any::<u32>(), map in any::<u32>(), levels in any::<u32>(),
                                 x in wild64(), h in wild64(), th in wild64(), kk in wild64()) {
        if let Ok(v) = hitex_core::terrain::active_area(fov, px, map, levels) {
            prop_assert!(v.len() <= 64);
        }
        let _ = hitex_core::terrain::level_at(x, h, th, kk);
    }
}
