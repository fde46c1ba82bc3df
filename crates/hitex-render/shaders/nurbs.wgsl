// The NURBS fragment program. Twin of src/cpu/nurbs.rs (and of
// hitex-core nurbs::{find_span, basis_ders_paper}): same packed inputs, same
// steps in the same order; change both together.
//
// Textures as in the paper: u knots and v knots (one row per pid, texel 0 =
// knot count), control points (one row per pid, texel 0 = (p, q, nu, nv),
// then homogeneous (wx, wy, wz, w)). Any degree up to MAX_DEGREE, by loops.

const MAX_DEGREE: i32 = 15;

struct Frame {
    view_proj: mat4x4<f32>,
    camera: vec4<f32>,
    light: vec4<f32>,
    params: vec4<u32>, // mode, isophote bands, stripes, flags (1: prepared kernels, 2: patch boundaries, 4: isolines, 8: sections, 16: edges)
    ranges: vec4<f32>, // curvature range lo, hi (deviation: tolerance, range); ambient; 1 / tool radius
    background: vec4<f32>,
    model: vec4<f32>, // bounding sphere: centre, radius
    pull: vec4<f32>, // draft: unit pull direction, sine of the tolerance
    lines: vec4<f32>, // sections: unit normal / spacing; isoparametric lines per patch and direction
    up: vec4<f32>, // the view's up axis (zebra bars, studio horizon)
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var knots_u: texture_2d<f32>;
@group(0) @binding(2) var knots_v: texture_2d<f32>;
@group(0) @binding(3) var control: texture_2d<f32>;
// trimming edges: row per patch, texel 0 = (count, albedo r, g, b; r < 0: default), then (u0, v0, u1, v1)
@group(0) @binding(4) var trims: texture_2d<f32>;
// signed deviation from a reference: row per patch, texel 0 = grid side G (0: none), then G×G values, v outer
@group(0) @binding(5) var deviation: texture_2d<f32>;
// edges drawn over the display mode: row per patch, texel 0 = (count, …), then per segment (u0, v0, u1, v1), (r, g, b, 0)
@group(0) @binding(6) var edges: texture_2d<f32>;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) patch_id: f32,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) u: f32,
    @location(2) v: f32,
    @location(3) patch_id: f32,
};

@vertex
fn vs_main(i: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = frame.view_proj * vec4<f32>(i.position, 1.0);
    o.normal = i.normal;
    o.u = i.uv.x;
    o.v = i.uv.y;
    o.patch_id = i.patch_id;
    return o;
}

// ---- knots: dir 0 = u, 1 = v ----

fn knot(dir: i32, pid: i32, i: i32) -> f32 {
    if dir == 0 {
        return textureLoad(knots_u, vec2<i32>(1 + i, pid), 0).x;
    }
    return textureLoad(knots_v, vec2<i32>(1 + i, pid), 0).x;
}

// find knot span (A2.1 with the end case m − p − 1)
fn find_span(dir: i32, pid: i32, n: i32, p: i32, u: f32) -> i32 {
    if u >= knot(dir, pid, n + 1) {
        var s = n;
        loop {
            if s <= p || knot(dir, pid, s) < knot(dir, pid, s + 1) { break; }
            s = s - 1;
        }
        return s;
    }
    if u <= knot(dir, pid, p) {
        var s = p;
        loop {
            if s >= n || knot(dir, pid, s + 1) > knot(dir, pid, s) { break; }
            s = s + 1;
        }
        return s;
    }
    var low = p;
    var high = n + 1;
    var mid = (low + high) / 2;
    loop {
        if u >= knot(dir, pid, mid) && u < knot(dir, pid, mid + 1) { break; }
        if u < knot(dir, pid, mid) { high = mid; } else { low = mid; }
        mid = (low + high) / 2;
    }
    return mid;
}

struct Basis {
    n: array<f32, 16>,
    d1: array<f32, 16>,
    d2: array<f32, 16>,
};

// derivatives of degree deg from the row of degree deg − 1 (paper eq. 6)
fn deriv(dir: i32, pid: i32, deg: i32, lower: array<f32, 16>, first: i32) -> array<f32, 16> {
    var lo = lower;
    var d: array<f32, 16>;
    let fdeg = f32(deg);
    for (var r = 0; r <= deg; r = r + 1) {
        let i = first + r - 1;
        var v = 0.0;
        if r >= 1 {
            let den = knot(dir, pid, i + deg) - knot(dir, pid, i);
            if den > 0.0 { v = v + lo[r - 1] * (1.0 / den); }
        }
        if r < deg {
            let den = knot(dir, pid, i + deg + 1) - knot(dir, pid, i + 1);
            if den > 0.0 { v = v - lo[r] * (1.0 / den); }
        }
        d[r] = fdeg * v;
    }
    return d;
}

// basis functions and derivatives by the triangular scheme (A2.2 + eq. 6)
fn basis(dir: i32, pid: i32, span: i32, u: f32, p: i32, second: bool) -> Basis {
    var n: array<f32, 16>;
    var left: array<f32, 16>;
    var right: array<f32, 16>;
    var row_p1: array<f32, 16>;
    var row_p2: array<f32, 16>;
    n[0] = 1.0;
    if p == 1 { row_p1[0] = 1.0; }
    if p == 2 { row_p2[0] = 1.0; }
    for (var j = 1; j <= p; j = j + 1) {
        left[j] = u - knot(dir, pid, span + 1 - j);
        right[j] = knot(dir, pid, span + j) - u;
        var saved = 0.0;
        for (var r = 0; r < j; r = r + 1) {
            let temp = n[r] * (1.0 / (knot(dir, pid, span + r + 1) - knot(dir, pid, span + 1 + r - j)));
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
        if j + 2 == p { row_p2 = n; }
        if j + 1 == p { row_p1 = n; }
    }
    var b: Basis;
    b.n = n;
    b.d1 = deriv(dir, pid, p, row_p1, span + 1 - p);
    if second && p >= 2 {
        let d1 = deriv(dir, pid, p - 1, row_p2, span + 2 - p);
        b.d2 = deriv(dir, pid, p, d1, span + 1 - p);
    }
    return b;
}

// ---- the prepared degree: bicubic, every loop bound a constant (the
// paper's one function per prepared degree; twin of basis_ders_fixed::<3, 4>) ----

struct Basis3 {
    n: array<f32, 4>,
    d1: array<f32, 4>,
    d2: array<f32, 4>,
};

fn deriv3(dir: i32, pid: i32, deg: i32, lower: array<f32, 4>, first: i32) -> array<f32, 4> {
    var lo = lower;
    var d: array<f32, 4>;
    let fdeg = f32(deg);
    for (var r = 0; r <= deg; r = r + 1) {
        let i = first + r - 1;
        var v = 0.0;
        if r >= 1 {
            let den = knot(dir, pid, i + deg) - knot(dir, pid, i);
            if den > 0.0 { v = v + lo[r - 1] * (1.0 / den); }
        }
        if r < deg {
            let den = knot(dir, pid, i + deg + 1) - knot(dir, pid, i + 1);
            if den > 0.0 { v = v - lo[r] * (1.0 / den); }
        }
        d[r] = fdeg * v;
    }
    return d;
}

fn basis3(dir: i32, pid: i32, span: i32, u: f32, second: bool) -> Basis3 {
    var n: array<f32, 4>;
    var left: array<f32, 4>;
    var right: array<f32, 4>;
    var row_p1: array<f32, 4>;
    var row_p2: array<f32, 4>;
    n[0] = 1.0;
    for (var j = 1; j <= 3; j = j + 1) {
        left[j] = u - knot(dir, pid, span + 1 - j);
        right[j] = knot(dir, pid, span + j) - u;
        var saved = 0.0;
        for (var r = 0; r < j; r = r + 1) {
            let temp = n[r] * (1.0 / (knot(dir, pid, span + r + 1) - knot(dir, pid, span + 1 + r - j)));
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
        if j == 1 { row_p2 = n; }
        if j == 2 { row_p1 = n; }
    }
    var b: Basis3;
    b.n = n;
    b.d1 = deriv3(dir, pid, 3, row_p1, span - 2);
    if second {
        let d1 = deriv3(dir, pid, 2, row_p2, span - 1);
        b.d2 = deriv3(dir, pid, 3, d1, span - 2);
    }
    return b;
}

// the second prepared degree: quintic (twin of basis_ders_fixed::<5, 6>)
fn deriv5(dir: i32, pid: i32, deg: i32, lower: array<f32, 6>, first: i32) -> array<f32, 6> {
    var lo = lower;
    var d: array<f32, 6>;
    let fdeg = f32(deg);
    for (var r = 0; r <= deg; r = r + 1) {
        let i = first + r - 1;
        var v = 0.0;
        if r >= 1 {
            let den = knot(dir, pid, i + deg) - knot(dir, pid, i);
            if den > 0.0 { v = v + lo[r - 1] * (1.0 / den); }
        }
        if r < deg {
            let den = knot(dir, pid, i + deg + 1) - knot(dir, pid, i + 1);
            if den > 0.0 { v = v - lo[r] * (1.0 / den); }
        }
        d[r] = fdeg * v;
    }
    return d;
}

fn basis5(dir: i32, pid: i32, span: i32, u: f32, second: bool) -> Basis {
    var n: array<f32, 6>;
    var left: array<f32, 6>;
    var right: array<f32, 6>;
    var row_p1: array<f32, 6>;
    var row_p2: array<f32, 6>;
    n[0] = 1.0;
    for (var j = 1; j <= 5; j = j + 1) {
        left[j] = u - knot(dir, pid, span + 1 - j);
        right[j] = knot(dir, pid, span + j) - u;
        var saved = 0.0;
        for (var r = 0; r < j; r = r + 1) {
            let temp = n[r] * (1.0 / (knot(dir, pid, span + r + 1) - knot(dir, pid, span + 1 + r - j)));
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
        if j == 3 { row_p2 = n; }
        if j == 4 { row_p1 = n; }
    }
    let d1 = deriv5(dir, pid, 5, row_p1, span - 4);
    var d2: array<f32, 6>;
    if second {
        let e1 = deriv5(dir, pid, 4, row_p2, span - 3);
        d2 = deriv5(dir, pid, 5, e1, span - 4);
    }
    var b: Basis;
    for (var r = 0; r < 6; r = r + 1) {
        b.n[r] = n[r];
        b.d1[r] = d1[r];
        b.d2[r] = d2[r];
    }
    return b;
}

// the basis of a prepared degree (3 or 5), widened to the loops' arrays
fn prepared_basis(dir: i32, pid: i32, span: i32, u: f32, p: i32, second: bool) -> Basis {
    if p == 5 {
        return basis5(dir, pid, span, u, second);
    }
    let b3 = basis3(dir, pid, span, u, second);
    var b: Basis;
    var n = b3.n;
    var d1 = b3.d1;
    var d2 = b3.d2;
    for (var r = 0; r < 4; r = r + 1) {
        b.n[r] = n[r];
        b.d1[r] = d1[r];
        b.d2[r] = d2[r];
    }
    return b;
}

struct Sums {
    a: array<vec4<f32>, 6>,
};

fn sums3(pid: i32, bu: Basis3, bv: Basis3, nu: i32, i0: i32, j0: i32, second: bool) -> Sums {
    var un = bu.n;
    var u1 = bu.d1;
    var u2 = bu.d2;
    var vn = bv.n;
    var v1 = bv.d1;
    var v2 = bv.d2;
    var out: Sums;
    for (var s = 0; s < 4; s = s + 1) {
        let row = (j0 + s) * nu + i0;
        var t0 = vec4<f32>(0.0);
        var t1 = vec4<f32>(0.0);
        var t2 = vec4<f32>(0.0);
        for (var r = 0; r < 4; r = r + 1) {
            let c = textureLoad(control, vec2<i32>(1 + row + r, pid), 0);
            t0 = t0 + c * un[r];
            t1 = t1 + c * u1[r];
            if second { t2 = t2 + c * u2[r]; }
        }
        out.a[0] = out.a[0] + t0 * vn[s];
        out.a[1] = out.a[1] + t1 * vn[s];
        out.a[2] = out.a[2] + t0 * v1[s];
        if second {
            out.a[3] = out.a[3] + t2 * vn[s];
            out.a[4] = out.a[4] + t1 * v1[s];
            out.a[5] = out.a[5] + t0 * v2[s];
        }
    }
    return out;
}

struct Eval {
    s: vec3<f32>,
    su: vec3<f32>,
    sv: vec3<f32>,
    suu: vec3<f32>,
    suv: vec3<f32>,
    svv: vec3<f32>,
};

fn eval_patch(pid: i32, u_in: f32, v_in: f32, second: bool) -> Eval {
    // pid header
    let head = textureLoad(control, vec2<i32>(0, pid), 0);
    let p = i32(head.x);
    let q = i32(head.y);
    let nu = i32(head.z);
    let nv = i32(head.w);
    // clamp into the domain
    let u = min(max(u_in, knot(0, pid, p)), knot(0, pid, nu));
    let v = min(max(v_in, knot(1, pid, q)), knot(1, pid, nv));
    // find knot span
    let su = find_span(0, pid, nu - 1, p, u);
    let sv = find_span(1, pid, nv - 1, q, v);
    // basis functions and derivatives (paper's form), then the homogeneous sums
    var sm: Sums;
    let prep = (frame.params.w & 1u) == 1u;
    let prepared_pq = prep && (p == 3 || p == 5) && (q == 3 || q == 5);
    if prep && p == 3 && q == 3 {
        let bu3 = basis3(0, pid, su, u, second);
        let bv3 = basis3(1, pid, sv, v, second);
        sm = sums3(pid, bu3, bv3, nu, su - 3, sv - 3, second);
    } else {
        var bu: Basis;
        var bv: Basis;
        if prepared_pq {
            bu = prepared_basis(0, pid, su, u, p, second);
            bv = prepared_basis(1, pid, sv, v, q, second);
        } else {
            bu = basis(0, pid, su, u, p, second);
            bv = basis(1, pid, sv, v, q, second);
        }
        var bun = bu.n;
        var bu1 = bu.d1;
        var bu2 = bu.d2;
        var bvn = bv.n;
        var bv1 = bv.d1;
        var bv2 = bv.d2;
        for (var s = 0; s <= q; s = s + 1) {
            let row = (sv - q + s) * nu + su - p;
            var t0 = vec4<f32>(0.0);
            var t1 = vec4<f32>(0.0);
            var t2 = vec4<f32>(0.0);
            for (var r = 0; r <= p; r = r + 1) {
                let c = textureLoad(control, vec2<i32>(1 + row + r, pid), 0);
                t0 = t0 + c * bun[r];
                t1 = t1 + c * bu1[r];
                if second { t2 = t2 + c * bu2[r]; }
            }
            sm.a[0] = sm.a[0] + t0 * bvn[s];
            sm.a[1] = sm.a[1] + t1 * bvn[s];
            sm.a[2] = sm.a[2] + t0 * bv1[s];
            if second {
                sm.a[3] = sm.a[3] + t2 * bvn[s];
                sm.a[4] = sm.a[4] + t1 * bv1[s];
                sm.a[5] = sm.a[5] + t0 * bv2[s];
            }
        }
    }
    let a0 = sm.a[0];
    let a1 = sm.a[1];
    let a2 = sm.a[2];
    let a3 = sm.a[3];
    let a4 = sm.a[4];
    let a5 = sm.a[5];
    // rational quotient rule, one division (1/w) for every term
    var e: Eval;
    let rw = 1.0 / a0.w;
    e.s = a0.xyz * rw;
    e.su = (a1.xyz - e.s * a1.w) * rw;
    e.sv = (a2.xyz - e.s * a2.w) * rw;
    if second {
        e.suu = (a3.xyz - e.su * (2.0 * a1.w) - e.s * a3.w) * rw;
        e.suv = (a4.xyz - e.su * a2.w - e.sv * a1.w - e.s * a4.w) * rw;
        e.svv = (a5.xyz - e.sv * (2.0 * a2.w) - e.s * a5.w) * rw;
    }
    return e;
}

fn exact_normal(e: Eval, fallback: vec3<f32>) -> vec3<f32> {
    let n = cross(e.su, e.sv);
    let scale = length(e.su) + length(e.sv);
    if length(n) > 1e-6 * scale * scale {
        return normalize(n);
    }
    if length(fallback) > 0.0 {
        return normalize(fallback);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

fn curvatures(e: Eval, n: vec3<f32>) -> vec2<f32> {
    let ee = dot(e.su, e.su);
    let ff = dot(e.su, e.sv);
    let gg = dot(e.sv, e.sv);
    let l = dot(e.suu, n);
    let m = dot(e.suv, n);
    let nn = dot(e.svv, n);
    let det = ee * gg - ff * ff;
    if abs(det) <= 1e-30 {
        return vec2<f32>(0.0);
    }
    return vec2<f32>((l * nn - m * m) / det, (ee * nn - 2.0 * ff * m + gg * l) / (2.0 * det));
}

fn diverging(t_in: f32) -> vec3<f32> {
    let t = clamp(t_in, -1.0, 1.0);
    let white = vec3<f32>(0.97);
    if t < 0.0 {
        return mix(white, vec3<f32>(0.12, 0.28, 0.85), -t);
    }
    return mix(white, vec3<f32>(0.85, 0.15, 0.12), t);
}

fn isophote(n: vec3<f32>, l: vec3<f32>, bands: u32) -> vec3<f32> {
    let angle = acos(clamp(dot(n, l), -1.0, 1.0));
    let band = i32(floor(angle / 3.14159265358979 * f32(bands)));
    if band % 2 == 0 {
        return vec3<f32>(0.95, 0.85, 0.32);
    }
    return vec3<f32>(0.10, 0.12, 0.20);
}

// principal curvatures (k1 >= k2) from (Gaussian, mean)
fn principal(kh: vec2<f32>) -> vec2<f32> {
    let r = sqrt(max(kh.y * kh.y - kh.x, 0.0));
    return vec2<f32>(kh.y + r, kh.y - r);
}

// radius classes: concave tighter than the tool (1/R = inv_radius), concave, convex or flat
fn reach_class(e: Eval, facing: vec3<f32>, n: vec3<f32>, light: vec3<f32>, inv_radius: f32) -> vec3<f32> {
    let k1 = principal(curvatures(e, facing)).x;
    var base = vec3<f32>(0.72, 0.75, 0.80);
    if k1 > inv_radius {
        base = vec3<f32>(0.86, 0.18, 0.15);
    } else if k1 > 0.01 * inv_radius {
        base = vec3<f32>(0.30, 0.50, 0.90);
    }
    return base * (0.3 + 0.7 * abs(dot(n, light)));
}

// draft classes: positive beyond the tolerance, within it, negative beyond it
fn draft(facing: vec3<f32>, n: vec3<f32>, light: vec3<f32>, pull: vec4<f32>) -> vec3<f32> {
    let s = dot(facing, pull.xyz);
    var base = vec3<f32>(0.96, 0.80, 0.16);
    if s > pull.w {
        base = vec3<f32>(0.20, 0.72, 0.30);
    } else if s < -pull.w {
        base = vec3<f32>(0.86, 0.18, 0.15);
    }
    return base * (0.3 + 0.7 * abs(dot(n, light)));
}

// values at or below this mean "no reference near" (a sentinel: no NaN in shaders)
fn no_data(x: f32) -> bool {
    return x <= -1.0e38;
}

// the patch's deviation grid at (u, v), bilinear; -3e38 where there is none
fn deviation_at(pid: i32, u: f32, v: f32) -> f32 {
    let g = i32(textureLoad(deviation, vec2<i32>(0, pid), 0).x);
    if g < 2 {
        return -3.0e38;
    }
    let d = domain(pid);
    var s = 0.0;
    if d.y > d.x { s = clamp((u - d.x) / (d.y - d.x), 0.0, 1.0) * f32(g - 1); }
    var r = 0.0;
    if d.w > d.z { r = clamp((v - d.z) / (d.w - d.z), 0.0, 1.0) * f32(g - 1); }
    let i = min(i32(floor(s)), g - 2);
    let j = min(i32(floor(r)), g - 2);
    let a = s - f32(i);
    let b = r - f32(j);
    let c0 = textureLoad(deviation, vec2<i32>(1 + j * g + i, pid), 0).x;
    let c1 = textureLoad(deviation, vec2<i32>(2 + j * g + i, pid), 0).x;
    let c2 = textureLoad(deviation, vec2<i32>(1 + (j + 1) * g + i, pid), 0).x;
    let c3 = textureLoad(deviation, vec2<i32>(2 + (j + 1) * g + i, pid), 0).x;
    if no_data(c0) || no_data(c1) || no_data(c2) || no_data(c3) {
        return -3.0e38;
    }
    let top = c0 + (c1 - c0) * a;
    let bottom = c2 + (c3 - c2) * a;
    return top + (bottom - top) * b;
}

// deviation classes: within the tolerance, yellow to red outside, cyan to blue inside, grey no data
fn deviation_color(dv: f32, tol: f32, range: f32) -> vec3<f32> {
    if no_data(dv) {
        return vec3<f32>(0.42, 0.42, 0.45);
    }
    let a = abs(dv);
    if a <= tol {
        return vec3<f32>(0.20, 0.72, 0.30);
    }
    let span = range - tol;
    var t = 1.0;
    if span > 0.0 { t = clamp((a - tol) / span, 0.0, 1.0); }
    if dv > 0.0 {
        let lo = vec3<f32>(0.96, 0.86, 0.20);
        return lo + (vec3<f32>(0.86, 0.18, 0.15) - lo) * t;
    }
    let lo = vec3<f32>(0.45, 0.85, 0.90);
    return lo + (vec3<f32>(0.12, 0.28, 0.85) - lo) * t;
}

// how much of a light of extent c ± half along one angle covers x (degrees; a 1.5° ramp at its edge)
fn coverage(x: f32, c: f32, half: f32) -> f32 {
    return clamp((half - abs(x - c)) / 1.5 + 0.5, 0.0, 1.0);
}

// the radiance a mirror shows of the procedural studio (twin of cpu::nurbs::studio)
fn studio(n: vec3<f32>, view: vec3<f32>, forward: vec3<f32>, up: vec3<f32>) -> f32 {
    let r = n * (2.0 * dot(n, view)) - view;
    let elevation = degrees(asin(clamp(dot(r, up), -1.0, 1.0)));
    let h = forward - up * dot(forward, up);
    var back = vec3<f32>(-1.0, 0.0, 0.0);
    if length(h) > 0.0 {
        back = -normalize(h);
    }
    let side = cross(up, back);
    let azimuth = degrees(atan2(dot(r, side), dot(r, back)));
    var light = 0.03;
    if elevation >= 0.0 {
        light = 0.08 + 0.17 * elevation / 90.0;
    }
    light = max(light, coverage(elevation, 15.0, 6.0) * coverage(azimuth, 0.0, 70.0));
    light = max(light, coverage(elevation, 40.0, 6.0) * coverage(azimuth, 0.0, 55.0));
    light = max(light, coverage(elevation, 65.0, 6.0) * coverage(azimuth, 0.0, 40.0));
    light = max(light, 0.6 * coverage(elevation, -20.0, 5.0) * coverage(azimuth, 0.0, 80.0));
    light = max(light, 0.45 * coverage(elevation, -45.0, 5.0) * coverage(azimuth, 0.0, 60.0));
    return max(light, 0.8 * coverage(elevation, 25.0, 35.0) * coverage(azimuth, 100.0, 5.0));
}

fn zebra(n: vec3<f32>, view: vec3<f32>, up: vec3<f32>, stripes: u32) -> vec3<f32> {
    let r = n * (2.0 * dot(n, view)) - view;
    let elevation = asin(clamp(dot(r, up), -1.0, 1.0));
    let k = i32(floor((elevation / 3.14159265358979 + 0.5) * f32(stripes)));
    if k % 2 == 0 {
        return vec3<f32>(0.96);
    }
    return vec3<f32>(0.05);
}

fn highlight(p: vec3<f32>, n: vec3<f32>, e: vec3<f32>, origin: vec3<f32>, spacing: f32) -> vec3<f32> {
    let en = dot(e, n);
    if abs(en) < 1e-4 {
        return vec3<f32>(0.05);
    }
    let t = (dot(e, origin) - dot(e, p)) / en;
    let x = p + n * t;
    var d = vec3<f32>(1.0, 0.0, 0.0);
    let ez = cross(e, vec3<f32>(0.0, 0.0, 1.0));
    if length(ez) > 1e-3 {
        d = normalize(ez);
    }
    let c = cross(e, d);
    let k = i32(floor(dot(c, x - origin) / spacing));
    if ((k % 2) + 2) % 2 == 0 {
        return vec3<f32>(0.95, 0.95, 0.9);
    }
    return vec3<f32>(0.08, 0.1, 0.16);
}

// even–odd rule over the patch's trimming edges
fn trimmed_away(pid: i32, u: f32, v: f32) -> bool {
    let n = i32(textureLoad(trims, vec2<i32>(0, pid), 0).x);
    if n == 0 {
        return false;
    }
    var inside = false;
    for (var i = 1; i <= n; i = i + 1) {
        let e = textureLoad(trims, vec2<i32>(i, pid), 0);
        if (e.y > v) != (e.w > v) {
            let x = e.x + (v - e.y) * (e.z - e.x) / (e.w - e.y);
            if u < x {
                inside = !inside;
            }
        }
    }
    return !inside;
}

// how far past its boundary (domain side or trimming loop) a fragment is
// still drawn, in pixels: the trimming loops of faces meeting along an edge
// are different polylines of one curve; drawing each a little past its loop,
// behind the other, closes the seam (untrimmed sides are closed by the
// tessellation's boundary fans). Past a domain side: the parameter's
// overshoot in fwidths; past a trimming loop: the distance on screen to the
// nearest trimming edge, through the inverse of the (u, v) Jacobian
const SEAM_REACH: f32 = 0.75;

// the map from a parameter offset (du, dv) to its screen offset in units of
// r pixels, (xu, xv, yu, yv): the inverse of the Jacobian g = (du/dx, du/dy,
// dv/dx, dv/dy) over r; ok false where g is singular (u and v vary along one
// screen direction only) or not finite: |det·r| outside (1e-30, 1e30), the
// test of `to_pixels` in cpu/nurbs.rs, made before dividing
struct ToPixels {
    m: vec4<f32>,
    ok: bool,
};

fn to_pixels(g: vec4<f32>, r: f32) -> ToPixels {
    let dr = (g.x * g.w - g.y * g.z) * r;
    let ok = abs(dr) > 1.0e-30 && abs(dr) < 1.0e30;
    let s = 1.0 / select(1.0, dr, ok);
    return ToPixels(vec4<f32>(g.w * s, -g.y * s, -g.z * s, g.x * s), ok);
}

// squared screen distance, in the units of m, from (u, v) to the
// parameter-space segment e (x0, y0, x1, y1)
fn segment_d2(m: vec4<f32>, e: vec4<f32>, u: f32, v: f32) -> f32 {
    let pu = e.x - u;
    let pv = e.y - v;
    let qu = e.z - e.x;
    let qv = e.w - e.y;
    let a = vec2<f32>(m.x * pu + m.y * pv, m.z * pu + m.w * pv);
    let d = vec2<f32>(m.x * qu + m.y * qv, m.z * qu + m.w * qv);
    let dd = d.x * d.x + d.y * d.y;
    var k = 0.0;
    if dd > 0.0 {
        k = clamp(-(a.x * d.x + a.y * d.y) / dd, 0.0, 1.0);
    }
    let p = a + k * d;
    return p.x * p.x + p.y * p.y;
}

fn near_trim(pid: i32, u: f32, v: f32, g: vec4<f32>) -> bool {
    let tp = to_pixels(g, SEAM_REACH);
    if !tp.ok {
        return false;
    }
    let n = i32(textureLoad(trims, vec2<i32>(0, pid), 0).x);
    for (var i = 1; i <= n; i = i + 1) {
        let e = textureLoad(trims, vec2<i32>(i, pid), 0);
        if segment_d2(tp.m, e, u, v) <= 1.0 {
            return true;
        }
    }
    return false;
}

// half the width of drawn edges, in pixels
const EDGE_REACH: f32 = 1.5;

// the colour of the nearest drawn edge within EDGE_REACH pixels on screen of
// (u, v); x < 0: none
fn on_edge(pid: i32, u: f32, v: f32, g: vec4<f32>) -> vec4<f32> {
    let tp = to_pixels(g, EDGE_REACH);
    if !tp.ok {
        return vec4<f32>(-1.0);
    }
    let n = i32(textureLoad(edges, vec2<i32>(0, pid), 0).x);
    var best = 2.0;
    var c = vec4<f32>(-1.0);
    for (var i = 0; i < n; i = i + 1) {
        let d2 = segment_d2(tp.m, textureLoad(edges, vec2<i32>(1 + 2 * i, pid), 0), u, v);
        if d2 <= 1.0 && d2 < best {
            best = d2;
            c = textureLoad(edges, vec2<i32>(2 + 2 * i, pid), 0);
        }
    }
    return c;
}

// the patch's parameter domain: (u0, u1, v0, v1)
fn domain(pid: i32) -> vec4<f32> {
    let head = textureLoad(control, vec2<i32>(0, pid), 0);
    return vec4<f32>(
        knot(0, pid, i32(head.x)),
        knot(0, pid, i32(head.z)),
        knot(1, pid, i32(head.y)),
        knot(1, pid, i32(head.w)),
    );
}

// where a fragment lies against its patch's boundary: 0 inside, 1 past it
// within the seam reach (drawn behind any surface truly there), 2 beyond
// (discarded)
fn reach(pid: i32, u: f32, v: f32, g: vec4<f32>) -> u32 {
    let fu = abs(g.x) + abs(g.y);
    let fv = abs(g.z) + abs(g.w);
    let d = domain(pid);
    let ou = max(d.x - u, u - d.y);
    let ov = max(d.z - v, v - d.w);
    if ou > SEAM_REACH * fu || ov > SEAM_REACH * fv {
        return 2u;
    }
    if trimmed_away(pid, u, v) {
        if near_trim(pid, u, v, g) {
            return 1u;
        }
        return 2u;
    }
    if ou > 0.0 || ov > 0.0 {
        return 1u;
    }
    return 0u;
}

// seam fragments are drawn as if this much farther from the eye
const SEAM_DEPTH_SCALE: f32 = 1.005;

fn on_boundary(pid: i32, u: f32, v: f32, fu: f32, fv: f32) -> bool {
    let d = domain(pid);
    let du = min(u - d.x, d.y - u);
    let dv = min(v - d.z, d.w - v);
    return du < fu || dv < fv;
}

// distance of x to the nearest whole number
fn off_whole(x: f32) -> f32 {
    return abs(x - floor(x + 0.5));
}

// on one of n isoparametric lines per direction of the patch, within half a pixel
fn on_isoline(pid: i32, u: f32, v: f32, fu: f32, fv: f32, n: f32) -> bool {
    let d = domain(pid);
    let su = (d.y - d.x) / n;
    let sv = (d.w - d.z) / n;
    return off_whole((u - d.x) / su) * su < 0.5 * fu || off_whole((v - d.z) / sv) * sv < 0.5 * fv;
}

// the exact point on a section plane P·a = k within half a pixel; g = (du/dx, du/dy, dv/dx, dv/dy)
fn on_section(e: Eval, a: vec3<f32>, g: vec4<f32>) -> bool {
    let s = dot(e.s, a);
    let su = dot(e.su, a);
    let sv = dot(e.sv, a);
    let width = abs(su * g.x + sv * g.z) + abs(su * g.y + sv * g.w);
    return off_whole(s) < 0.5 * width;
}


struct FsOut {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
};

@fragment
fn fs_main(in: VsOut) -> FsOut {
    let pid = i32(round(in.patch_id));
    let mode = frame.params.x;
    // fine derivatives for the boundary overlay, taken in uniform control flow
    let g = vec4<f32>(dpdxFine(in.u), dpdyFine(in.u), dpdxFine(in.v), dpdyFine(in.v));
    let fu = abs(g.x) + abs(g.y);
    let fv = abs(g.z) + abs(g.w);
    // past the domain or trimmed away, beyond the seam reach: discarded
    var at = reach(pid, in.u, in.v, g);
    // boundary-fan fragments (patch index marked by a quarter) are seam fragments
    if at == 0u && abs(in.patch_id - round(in.patch_id)) > 0.125 {
        at = 1u;
    }
    if at == 2u {
        discard;
    }
    let second = mode == MODE_GAUSS || mode == MODE_MEAN || mode == MODE_RADIUS || mode == MODE_K1 || mode == MODE_K2;
    // exact point and derivatives
    let e = eval_patch(pid, in.u, in.v, second);
    let vn = in.normal;
    var n = exact_normal(e, vn);
    // the surface's own orientation (Su × Sv), for the draft's sign
    let facing = n;
    // two-sided
    let view = normalize(frame.camera.xyz - e.s);
    if dot(n, view) < 0.0 {
        n = -n;
    }
    // depth of the exact point (of a seam fragment: pushed back)
    var at_depth = e.s;
    if at == 1u {
        at_depth = frame.camera.xyz + (e.s - frame.camera.xyz) * SEAM_DEPTH_SCALE;
    }
    let clip = frame.view_proj * vec4<f32>(at_depth, 1.0);
    var out: FsOut;
    out.depth = clip.z / clip.w;
    let light = frame.light.xyz;
    var c: vec3<f32>;
    if mode == MODE_ISOPHOTE {
        c = isophote(n, light, frame.params.y);
    } else if mode == MODE_REFLECTION {
        let l = linear_to_srgb(0.9 * studio(n, view, frame.model.xyz - frame.camera.xyz, frame.up.xyz));
        c = vec3<f32>(l);
    } else if mode == MODE_ZEBRA {
        c = zebra(n, view, frame.up.xyz, frame.params.z);
    } else if mode == MODE_GAUSS || mode == MODE_MEAN {
        let kh = curvatures(e, n);
        var value = kh.y;
        if mode == MODE_GAUSS { value = kh.x; }
        c = diverging(value / frame.ranges.y);
    } else if mode == MODE_VERTEX_NORMALS {
        var m = vec3<f32>(0.0, 0.0, 1.0);
        if length(vn) > 0.0 { m = normalize(vn); }
        if dot(m, view) < 0.0 { m = -m; }
        c = isophote(m, light, frame.params.y);
    } else if mode == MODE_NORMAL {
        c = n * 0.5 + vec3<f32>(0.5);
    } else if mode == MODE_K1 || mode == MODE_K2 {
        let k = principal(curvatures(e, n));
        var value = k.y;
        if mode == MODE_K1 { value = k.x; }
        c = diverging(value / frame.ranges.y);
    } else if mode == MODE_DRAFT {
        c = draft(facing, n, light, frame.pull);
    } else if mode == MODE_RADIUS {
        c = reach_class(e, facing, n, light, frame.ranges.w);
    } else if mode == MODE_DEVIATION {
        c = deviation_color(deviation_at(pid, in.u, in.v), frame.ranges.x, frame.ranges.y) * (0.3 + 0.7 * abs(dot(n, light)));
    } else if mode == MODE_HIGHLIGHT {
        let r = frame.model.w;
        c = highlight(e.s, n, light, frame.model.xyz + light * (2.0 * r), 2.0 * r / f32(max(frame.params.z, 1u)));
    } else {
        // the patch's own colour (texel 0 of its trim row; r < 0: the default grey)
        let head = textureLoad(trims, vec2<i32>(0, pid), 0);
        var albedo = vec3<f32>(0.72, 0.75, 0.80);
        if head.y >= 0.0 { albedo = head.yzw; }
        let ndl = max(dot(n, light), 0.0);
        let h = normalize(light + view);
        var spec = 0.0;
        if ndl > 0.0 { spec = 0.35 * pow(max(dot(n, h), 0.0), 48.0); }
        let lin = albedo * (frame.ranges.z + ndl) + vec3<f32>(spec);
        c = vec3<f32>(linear_to_srgb(lin.x), linear_to_srgb(lin.y), linear_to_srgb(lin.z));
    }
    if (frame.params.w & 4u) == 4u && on_isoline(pid, in.u, in.v, fu, fv, frame.lines.w) {
        c = ISOLINE_RGB;
    }
    if (frame.params.w & 8u) == 8u && on_section(e, frame.lines.xyz, g) {
        c = SECTION_RGB;
    }
    if (frame.params.w & 16u) == 16u {
        let ec = on_edge(pid, in.u, in.v, g);
        if ec.x >= 0.0 {
            c = ec.xyz;
        }
    }
    if (frame.params.w & 2u) == 2u && on_boundary(pid, in.u, in.v, fu, fv) {
        c = vec3<f32>(20.0 / 255.0, 20.0 / 255.0, 24.0 / 255.0);
    }
    out.color = vec4<f32>(c, 1.0);
    return out;
}
