use super::*;

#[test]
fn arc_parameters_land_on_their_angles() {
    for (a0, a1) in [(0.0, 0.3), (-1.0, 2.0), (0.5, 0.5 + TAU), (2.0, 2.0 + PI)] {
        let arc = Arc::new(a0, a1).unwrap();
        let (knots, ctrl) = arc.control();
        let pw: Vec<[f64; 4]> = ctrl.iter().map(|c| [c.0 * c.2, c.1 * c.2, 0.0, c.2]).collect();
        let curve = Curve::Spline { degree: 2, knots, pw };
        for k in 0..=40 {
            let phi = a0 + (a1 - a0) * k as f64 / 40.0;
            let p = curve.point(arc.param(phi));
            assert!((p.x - phi.cos()).abs() < 1e-12 && (p.y - phi.sin()).abs() < 1e-12, "{a0}..{a1} at {phi}: {p}");
        }
    }
}

#[test]
fn analytic_surfaces_convert_exactly() {
    let f = Frame::new(DVec3::new(1.0, -2.0, 0.5), DVec3::new(0.3, 0.2, 1.0), DVec3::X);
    let kinds = [
        Kind::Plane,
        Kind::Cylinder { r: 2.0 },
        Kind::Cone { r: 1.0, tan: 0.4 },
        Kind::Sphere { r: 3.0 },
        Kind::Torus { big: 4.0, small: 1.0 },
    ];
    for kind in kinds {
        let s = Surface::new(f, kind);
        let win = match s.kind {
            Kind::Sphere { .. } => [(0.2, 5.0), (-1.2, 0.9)],
            Kind::Torus { .. } => [(-1.0, 2.5), (0.0, TAU)],
            _ => [(-0.7, 2.9), (-1.0, 3.0)],
        };
        let (n, map) = s.to_nurbs(win).unwrap();
        for i in 0..=12 {
            for j in 0..=12 {
                let st = DVec2::new(
                    win[0].0 + (win[0].1 - win[0].0) * i as f64 / 12.0,
                    win[1].0 + (win[1].1 - win[1].0) * j as f64 / 12.0,
                );
                let uv = map.apply(st);
                let (a, b) = (s.point(st), DVec3::from_array(n.point(uv[0], uv[1])));
                assert!(a.distance(b) < 1e-10, "{:?} at {st}: {a} vs {b}", s.kind);
                // and the point inverts to its parameters
                let back = s.project(a, Some(st + DVec2::splat(0.01)));
                assert!(s.point(back).distance(a) < 1e-9, "{:?}: {back} for {st}", s.kind);
            }
        }
    }
}
