//! Point + normal evaluation throughput: hitex's f64 reference and f32 path
//! (the CPU twin of the shader) against curvo and truck-geometry, on the same
//! surfaces and parameters, with each one's largest deviation from hitex's
//! f64 reference (relative to the surface's size) printed first.
//!
//! `cargo bench -p hitex-peers`

// index loops mirror the kernels they time
#![allow(clippy::needless_range_loop)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use hitex_core::nurbs::surface::rational_derivs;
use hitex_core::nurbs::{NurbsSurface, basis_ders_fixed, find_span};
use std::hint::black_box;

/// The paper's `surface`: rational bicubic, 6×14 control points, non-uniform knots.
fn surface() -> NurbsSurface {
    let (nu, nv) = (6usize, 14usize);
    let mut pts = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let x = i as f64 / (nu - 1) as f64 * 4.0 - 2.0;
            let y = j as f64 / (nv - 1) as f64 * 9.0 - 4.5;
            let z = 0.35 * x * x - 0.12 * y * y + 0.45 * (0.9 * y).sin() + 0.2 * (1.7 * x).cos();
            pts.push([x, y, z, 1.0 + 0.35 * (((i * 7 + j * 3) % 5) as f64 / 4.0)]);
        }
    }
    let ku = vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.62, 1.0, 1.0, 1.0, 1.0];
    let kv = vec![0.0, 0.0, 0.0, 0.0, 0.06, 0.15, 0.21, 0.33, 0.42, 0.5, 0.61, 0.7, 0.77, 0.9, 1.0, 1.0, 1.0, 1.0];
    NurbsSurface::new(3, 3, nu, nv, ku, kv, pts).expect("valid surface")
}

/// Parameters in raster order over the domain (as a fragment program sees them).
fn params(n: usize) -> Vec<(f64, f64)> {
    (0..n * n).map(|k| (((k % n) as f64 + 0.5) / n as f64, ((k / n) as f64 + 0.5) / n as f64)).collect()
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

struct F32Surface {
    ku: Vec<f32>,
    kv: Vec<f32>,
    pw: Vec<[f32; 4]>,
    nu: usize,
    nv: usize,
}

/// hitex's f32 fast path: prepared bicubic kernel, point and normal.
fn eval_f32(s: &F32Surface, u: f32, v: f32) -> ([f32; 3], [f32; 3]) {
    let su = find_span(s.nu - 1, 3, u, &s.ku);
    let sv = find_span(s.nv - 1, 3, v, &s.kv);
    let bu = basis_ders_fixed::<f32, 3, 4>(su, u, &s.ku, false);
    let bv = basis_ders_fixed::<f32, 3, 4>(sv, v, &s.kv, false);
    let mut a = [[0.0f32; 4]; 3];
    for (sj, row_v) in (0..4).map(|j| (j, (sv - 3 + j) * s.nu + su - 3)) {
        let mut t0 = [0.0f32; 4];
        let mut t1 = [0.0f32; 4];
        for r in 0..4 {
            let c = s.pw[row_v + r];
            for k in 0..4 {
                t0[k] += bu[0][r] * c[k];
                t1[k] += bu[1][r] * c[k];
            }
        }
        for k in 0..4 {
            a[0][k] += bv[0][sj] * t0[k];
            a[1][k] += bv[0][sj] * t1[k];
            a[2][k] += bv[1][sj] * t0[k];
        }
    }
    let w = a[0][3];
    let p = [a[0][0] / w, a[0][1] / w, a[0][2] / w];
    let du = [(a[1][0] - p[0] * a[1][3]) / w, (a[1][1] - p[1] * a[1][3]) / w, (a[1][2] - p[2] * a[1][3]) / w];
    let dv = [(a[2][0] - p[0] * a[2][3]) / w, (a[2][1] - p[1] * a[2][3]) / w, (a[2][2] - p[2] * a[2][3]) / w];
    let n = [du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2], du[0] * dv[1] - du[1] * dv[0]];
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (p, [n[0] / l, n[1] / l, n[2] / l])
}

fn bench(c: &mut Criterion) {
    let s = surface();
    let pw = s.homogeneous();
    let ps = params(64);
    let size = {
        let (lo, hi) = s.bounds();
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
    };
    let reference: Vec<([f64; 3], [f64; 3])> = ps
        .iter()
        .map(|&(u, v)| {
            let d = rational_derivs(3, 3, s.count_u, s.count_v, &s.knots_u, &s.knots_v, &pw, u, v, 1);
            (d.d[0][0], normalize(cross(d.d[1][0], d.d[0][1])))
        })
        .collect();
    let f32s = F32Surface {
        ku: s.knots_u.iter().map(|&x| x as f32).collect(),
        kv: s.knots_v.iter().map(|&x| x as f32).collect(),
        pw: pw.iter().map(|c| c.map(|x| x as f32)).collect(),
        nu: s.count_u,
        nv: s.count_v,
    };
    // curvo: homogeneous control points, rows along u
    let cv = curvo::prelude::NurbsSurface3D::<f64>::new(
        3,
        3,
        s.knots_u.clone(),
        s.knots_v.clone(),
        (0..s.count_u)
            .map(|i| {
                (0..s.count_v)
                    .map(|j| {
                        let c = pw[j * s.count_u + i];
                        nalgebra::Point4::new(c[0], c[1], c[2], c[3])
                    })
                    .collect()
            })
            .collect(),
    );
    // truck-geometry: homogeneous Vector4, rows along u
    use truck_geometry::prelude::*;
    let tk = NurbsSurface::new(BSplineSurface::new(
        (KnotVec::from(s.knots_u.clone()), KnotVec::from(s.knots_v.clone())),
        (0..s.count_u)
            .map(|i| {
                (0..s.count_v)
                    .map(|j| {
                        let c = pw[j * s.count_u + i];
                        Vector4::new(c[0], c[1], c[2], c[3])
                    })
                    .collect()
            })
            .collect(),
    ));

    // deviations from the f64 reference
    let dev = |f: &dyn Fn(f64, f64) -> ([f64; 3], [f64; 3])| -> (f64, f64) {
        ps.iter().zip(&reference).fold((0.0f64, 0.0f64), |(dp, dn), (&(u, v), (rp, rn))| {
            let (p, n) = f(u, v);
            let ep = (0..3).map(|k| (p[k] - rp[k]).abs()).fold(0.0, f64::max) / size;
            let en = (0..3).map(|k| (n[k] - rn[k]).abs()).fold(0.0, f64::max);
            (dp.max(ep), dn.max(en))
        })
    };
    let (a, b) = dev(&|u, v| {
        let (p, n) = eval_f32(&f32s, u as f32, v as f32);
        (p.map(|x| x as f64), n.map(|x| x as f64))
    });
    println!("hitex f32: max point deviation {a:.2e} of the model size, max normal deviation {b:.2e}");
    // the block evaluator: 16 consecutive parameters of a row a call
    let packed = hitex_render::nurbs::PackedNurbs::new(std::slice::from_ref(&s));
    let blocks: Vec<([f32; 16], [f32; 16])> = ps
        .chunks_exact(16)
        .map(|c| (std::array::from_fn(|l| c[l].0 as f32), std::array::from_fn(|l| c[l].1 as f32)))
        .collect();
    let eval_blocks = |out: &mut Vec<([f64; 3], [f64; 3])>| {
        let mut refused = 0;
        for (u, v) in &blocks {
            match hitex_render::cpu::nurbs::eval_bicubic_block(&packed, 0, u, v) {
                Some(b) => out.extend((0..16).map(|l| {
                    let p = [b.p[0][l], b.p[1][l], b.p[2][l]].map(|x| x as f64);
                    let n = [b.n[0][l], b.n[1][l], b.n[2][l]].map(|x| x as f64);
                    (p, n)
                })),
                None => {
                    refused += 1;
                    out.extend((0..16).map(|l| {
                        let (p, n) = eval_f32(&f32s, u[l], v[l]);
                        (p.map(|x| x as f64), n.map(|x| x as f64))
                    }))
                }
            }
        }
        refused
    };
    let mut block_out = Vec::new();
    let refused = eval_blocks(&mut block_out);
    let (a, b) =
        ps.iter().zip(&reference).zip(&block_out).fold((0.0f64, 0.0f64), |(dp, dn), ((_, (rp, rn)), (p, n))| {
            let ep = (0..3).map(|k| (p[k] - rp[k]).abs()).fold(0.0, f64::max) / size;
            let en = (0..3).map(|k| (n[k] - rn[k]).abs()).fold(0.0, f64::max);
            (dp.max(ep), dn.max(en))
        });
    println!(
        "hitex f32 block of 16 ({}): max point deviation {a:.2e} of the model size, max normal deviation {b:.2e}; {refused} of {} blocks straddle a knot and go per parameter",
        hitex_render::cpu::simd::level(),
        blocks.len()
    );
    let (a, b) = dev(&|u, v| {
        let p = cv.point_at(u, v);
        let n = cv.normal_at(u, v).normalize();
        ([p.x, p.y, p.z], [n.x, n.y, n.z])
    });
    println!("curvo:     max point deviation {a:.2e} of the model size, max normal deviation {b:.2e}");
    let (a, b) = dev(&|u, v| {
        let p = tk.subs(u, v);
        let n = ParametricSurface3D::normal(&tk, u, v);
        ([p.x, p.y, p.z], [n.x, n.y, n.z])
    });
    println!("truck:     max point deviation {a:.2e} of the model size, max normal deviation {b:.2e}");

    let mut g = c.benchmark_group("point+normal, rational bicubic 6x14");
    g.throughput(Throughput::Elements(ps.len() as u64));
    g.bench_function("hitex f64", |bch| {
        bch.iter(|| {
            for &(u, v) in &ps {
                let d = rational_derivs(3, 3, s.count_u, s.count_v, &s.knots_u, &s.knots_v, &pw, u, v, 1);
                black_box(normalize(cross(d.d[1][0], d.d[0][1])));
            }
        })
    });
    g.bench_function("hitex f32", |bch| {
        bch.iter(|| {
            for &(u, v) in &ps {
                black_box(eval_f32(&f32s, u as f32, v as f32));
            }
        })
    });
    g.bench_function("hitex f32 block of 16", |bch| {
        bch.iter(|| {
            for (u, v) in &blocks {
                match hitex_render::cpu::nurbs::eval_bicubic_block(&packed, 0, u, v) {
                    Some(b) => {
                        black_box(b);
                    }
                    None => {
                        for l in 0..16 {
                            black_box(eval_f32(&f32s, u[l], v[l]));
                        }
                    }
                }
            }
        })
    });
    g.bench_function("curvo", |bch| {
        bch.iter(|| {
            for &(u, v) in &ps {
                black_box((cv.point_at(u, v), cv.normal_at(u, v).normalize()));
            }
        })
    });
    g.bench_function("truck-geometry", |bch| {
        bch.iter(|| {
            for &(u, v) in &ps {
                black_box((tk.subs(u, v), ParametricSurface3D::normal(&tk, u, v)));
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
