// The flight fragment programs. Twin of `src/cpu/terrain.rs`: the same
// uniforms and page table, the same steps in the same order.

struct Fly {
    view_proj: mat4x4<f32>, // world (finest texels) to clip, for meshes
    eye: vec4<f32>,    // xyz eye (finest texels), w tan of half the horizontal FOV
    fwd: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    sizes: vec4<u32>,  // width, height, levels, maps per window side
    params: vec4<u32>, // sampler (SAMPLER_*), generic layer, its levels, its side
}

struct Pages {
    origins: array<vec4<i32>, 32>,  // per level: first map column, row
    slots: array<vec2<i32>>,        // per level and slot: (layer, level of the serving map); layer < 0: no data
}

// the sampler, fixed per pipeline (a SAMPLER_* code):
// each pipeline compiles only its own path (params.x carries the same code)
override SAMPLER: u32 = SAMPLER_TRILINEAR;

@group(0) @binding(0) var<uniform> fly: Fly;
@group(0) @binding(1) var<storage, read> pages: Pages;
@group(0) @binding(2) var maps: texture_2d_array<f32>;

const MAP: i32 = 256;
const GROUND: vec3<f32> = vec3<f32>(0.05, 0.06, 0.05);
// virtual levels a span may read beyond the coarsest
const VIRTUAL: i32 = 24;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // one triangle covering the screen
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

struct Hit {
    ok: bool,
    p: vec2<f32>,
}

// the ground point through pixel position (px, py); not ok at and above the horizon
fn ground(px: f32, py: f32) -> Hit {
    let w = f32(fly.sizes.x);
    let h = f32(fly.sizes.y);
    let tan_h = fly.eye.w;
    let sx = (2.0 * px / w - 1.0) * tan_h;
    let sy = (1.0 - 2.0 * py / h) * tan_h * h / w;
    let d = fly.fwd.xyz + fly.right.xyz * sx + fly.up.xyz * sy;
    if (d.z >= -1e-6) {
        return Hit(false, vec2<f32>(0.0));
    }
    let t = -fly.eye.z / d.z;
    return Hit(true, fly.eye.xy + d.xy * t);
}

// linear RGBA of texel (tx, ty) of level z through the page table
fn texel(z_in: u32, tx_in: i32, ty_in: i32) -> vec4<f32> {
    let per = i32(fly.sizes.w);
    var z = z_in;
    var tx = tx_in;
    var ty = ty_in;
    loop {
        let o = pages.origins[z].xy;
        let mx = (tx >> 8u) - o.x;
        let my = (ty >> 8u) - o.y;
        if (mx >= 0 && my >= 0 && mx < per && my < per) {
            let slot = pages.slots[i32(z) * per * per + my * per + mx];
            if (slot.x < 0) {
                return vec4<f32>(0.0);
            }
            // a coarser resident map stands in: its texel containing this one
            let k = z - u32(slot.y);
            let lx = (tx >> k) & (MAP - 1);
            let ly = (ty >> k) & (MAP - 1);
            return textureLoad(maps, vec2<i32>(lx, ly), slot.x, 0);
        }
        // outside the active area: the next coarser level covers it
        if (z == 0u) {
            return vec4<f32>(0.0);
        }
        z = z - 1u;
        tx = tx >> 1u;
        ty = ty >> 1u;
    }
    return vec4<f32>(0.0);
}

fn lerp2(c0: vec4<f32>, c1: vec4<f32>, c2: vec4<f32>, c3: vec4<f32>, f: vec2<f32>) -> vec4<f32> {
    let top = c0 + (c1 - c0) * f.x;
    let bot = c2 + (c3 - c2) * f.x;
    return top + (bot - top) * f.y;
}

fn bilinear(z: u32, p: vec2<f32>) -> vec4<f32> {
    let s = f32(1u << (fly.sizes.z - 1u - z));
    let q = p / s - vec2<f32>(0.5);
    let q0 = floor(q);
    let f = q - q0;
    let ix = i32(q0.x);
    let iy = i32(q0.y);
    return lerp2(texel(z, ix, iy), texel(z, ix + 1, iy), texel(z, ix, iy + 1), texel(z, ix + 1, iy + 1), f);
}

// eq. (2)–(4) at map point p with largest partial foot (finest texels per pixel)
fn trilinear(p: vec2<f32>, foot: f32) -> vec4<f32> {
    let levels = fly.sizes.z;
    let zf = clamp(f32(levels - 1u) - log2(max(foot, 1e-9)), 0.0, f32(levels - 1u));
    let z0 = u32(floor(zf));
    let z1 = min(z0 + 1u, levels - 1u);
    let t = zf - f32(z0);
    let s0 = bilinear(z0, p);
    var s1 = s0;
    if (z1 != z0 && t > 0.0) {
        s1 = bilinear(z1, p);
    }
    return s0 + (s1 - s0) * t;
}

// texel (tx, ty) of level k of the generic texture, repeating
fn generic_texel(k: u32, tx: i32, ty: i32) -> vec4<f32> {
    let n = i32(max(fly.params.w >> k, 1u));
    let x = ((tx % n) + n) % n;
    let y = ((ty % n) + n) % n;
    return textureLoad(maps, vec2<i32>(x, y), i32(fly.params.y + k), 0);
}

fn generic_one(k: u32, p: vec2<f32>) -> vec4<f32> {
    let s = f32(1u << k);
    let q = p / s - vec2<f32>(0.5);
    let q0 = floor(q);
    let ix = i32(q0.x);
    let iy = i32(q0.y);
    return lerp2(generic_texel(k, ix, iy), generic_texel(k, ix + 1, iy), generic_texel(k, ix, iy + 1),
        generic_texel(k, ix + 1, iy + 1), q - q0);
}

// trilinear from the generic texture at level-0 texel position p
fn generic(p: vec2<f32>, foot: f32) -> vec4<f32> {
    if (fly.params.z == 0u) {
        return vec4<f32>(1.0);
    }
    let last = fly.params.z - 1u;
    let lam = clamp(log2(max(foot, 1e-9)), 0.0, f32(last));
    let k0 = u32(floor(lam));
    let k1 = min(k0 + 1u, last);
    let t = lam - f32(k0);
    let a = generic_one(k0, p);
    var b = a;
    if (k1 != k0 && t > 0.0) {
        b = generic_one(k1, p);
    }
    return a + (b - a) * t;
}

// ---- span samplers (eq. (8)–(10)): the quad is the span ----

struct Span {
    p: array<vec2<f32>, 4>, // map points of the span's pixels (0,0) (1,0) (0,1) (1,1)
    ok: vec4<bool>,         // which points exist
}

fn catmull_rom(t: f32) -> vec4<f32> {
    let t2 = t * t;
    let t3 = t2 * t;
    return vec4<f32>(0.5 * (-t3 + 2.0 * t2 - t), 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t), 0.5 * (t3 - t2));
}

// this lane's value at finest-numbered level k (virtual above the coarsest)
fn span_level(s: Span, me: u32, k_in: i32, b: i32, bicubic: bool) -> vec4<f32> {
    let last = i32(fly.sizes.z) - 1;
    // a virtual level takes the coarsest level's values
    let k = min(k_in, last);
    let z = u32(last - k);
    let sc = exp2(-f32(k));
    var lo = vec2<i32>(2147483647);
    var hi = vec2<i32>(-2147483647);
    for (var i = 0u; i < 4u; i++) {
        if (s.ok[i]) {
            let f = vec2<i32>(floor(s.p[i] * sc - vec2<f32>(0.5)));
            lo = min(lo, f);
            hi = max(hi, f);
        }
    }
    let q = s.p[me] * sc - vec2<f32>(0.5);
    let q0 = floor(q);
    let t = q - q0;
    let f = vec2<i32>(q0);
    if (!bicubic) {
        return lerp2(texel(z, f.x, f.y), texel(z, f.x + 1, f.y), texel(z, f.x, f.y + 1), texel(z, f.x + 1, f.y + 1), t);
    }
    let o = lo - vec2<i32>(1) + max(hi - lo + vec2<i32>(4 - b), vec2<i32>(0)) / 2;
    let wx = catmull_rom(t.x);
    let wy = catmull_rom(t.y);
    var acc = vec4<f32>(0.0);
    var mn = vec4<f32>(1e30);
    var mx = vec4<f32>(-1e30);
    for (var j = 0; j < 4; j++) {
        let y = clamp(f.y + j - 1, o.y, o.y + b - 1);
        for (var i = 0; i < 4; i++) {
            let x = clamp(f.x + i - 1, o.x, o.x + b - 1);
            let c = texel(z, x, y);
            acc += c * (wx[i] * wy[j]);
            mn = min(mn, c);
            mx = max(mx, c);
        }
    }
    return clamp(acc, mn, mx);
}

fn span_sample(s: Span, me: u32) -> vec4<f32> {
    let sampler = SAMPLER;
    var b = 4;
    if (sampler == SAMPLER_SPAN3) {
        b = 3;
    }
    let bicubic = sampler == SAMPLER_BICUBIC;
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    for (var i = 0u; i < 4u; i++) {
        if (s.ok[i]) {
            lo = min(lo, s.p[i]);
            hi = max(hi, s.p[i]);
        }
    }
    let e = max(hi.x - lo.x, hi.y - lo.y);
    let lam = log2(2.0 * e / f32(b - 2));
    let cap = i32(fly.sizes.z) - 1 + VIRTUAL;
    var k = 0;
    var g = 0.0;
    if (lam > 0.0) {
        let f = floor(lam);
        if (f >= f32(cap)) {
            k = cap;
        } else {
            k = i32(f);
            g = lam - f;
        }
    }
    // rounding guard: the finer level's bilinear footprint must fit B texels
    loop {
        if (k >= cap) {
            break;
        }
        let sc = exp2(-f32(k));
        let d = floor(hi * sc - vec2<f32>(0.5)) - floor(lo * sc - vec2<f32>(0.5)) + vec2<f32>(2.0);
        if (d.x <= f32(b) && d.y <= f32(b)) {
            break;
        }
        k += 1;
    }
    let c0 = span_level(s, me, k, b, bicubic);
    if (g <= 0.0) {
        return c0;
    }
    let c1 = span_level(s, me, k + 1, b, bicubic);
    return c0 + (c1 - c0) * g;
}


fn sky(y: f32) -> vec3<f32> {
    let s = 1.0 - y / f32(fly.sizes.y);
    return vec3<f32>(0.55 + 0.2 * s, 0.68 + 0.15 * s, 0.86);
}

@fragment
fn fs_main(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let x = frag.x;
    let y = frag.y;
    if (SAMPLER != SAMPLER_TRILINEAR) {
        // the span this pixel belongs to: its four ground points, the same on every lane
        let x0 = floor(x * 0.5) * 2.0 + 0.5;
        let y0 = floor(y * 0.5) * 2.0 + 0.5;
        var s: Span;
        for (var i = 0u; i < 4u; i++) {
            let hit = ground(x0 + f32(i & 1u), y0 + f32(i >> 1u));
            s.p[i] = hit.p;
            s.ok[i] = hit.ok;
        }
        let me = u32(x - x0 + 0.5) + 2u * u32(y - y0 + 0.5);
        if (!s.ok[me]) {
            return encode(sky(y));
        }
        let c = span_sample(s, me);
        return encode(c.rgb + GROUND * (1.0 - c.a));
    }
    let a = ground(x, y);
    let b = ground(x + 1.0, y);
    let c = ground(x, y + 1.0);
    if (!(a.ok && b.ok && c.ok)) {
        return encode(sky(y));
    }
    // eq. (2): the largest partial of the screen-to-map mapping
    let d1 = abs(b.p - a.p);
    let d2 = abs(c.p - a.p);
    let foot = max(max(d1.x, d1.y), max(d2.x, d2.y));
    let s = trilinear(a.p, foot);
    return encode(s.rgb + GROUND * (1.0 - s.a));
}

// ---- meshes: the DEM and objects ----

struct MeshIn {
    @location(0) pos: vec3<f32>,
    @location(1) tex: vec2<f32>,
    @location(2) kind: f32,
    @location(3) shade: f32,
}

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) tex: vec2<f32>,
    @location(1) kind: f32,
    @location(2) shade: f32,
}

@vertex
fn vs_mesh(v: MeshIn) -> MeshOut {
    return MeshOut(fly.view_proj * vec4<f32>(v.pos, 1.0), v.tex, v.kind, v.shade);
}

@fragment
fn fs_mesh(in: MeshOut) -> @location(0) vec4<f32> {
    let p = in.tex;
    // fine differences: derivatives first, in uniform control flow
    let dx = dpdxFine(p);
    let dy = dpdyFine(p);
    let dxx = dpdyFine(dx);
    let foot = max(max(abs(dx.x), abs(dx.y)), max(abs(dy.x), abs(dy.y)));
    if (in.kind > 0.5) {
        let c = generic(p, foot);
        return encode(c.rgb * in.shade);
    }
    if (SAMPLER == SAMPLER_TRILINEAR) {
        let s = trilinear(p, foot);
        return encode(s.rgb + GROUND * (1.0 - s.a));
    }
    // the quad's four points from this lane's point and the fine differences:
    // p(i, j) = p00 + i dx0 + j dy0 + i j dxx
    let i = f32(u32(in.clip.x) & 1u);
    let j = f32(u32(in.clip.y) & 1u);
    let p00 = p - i * dx - j * dy + i * j * dxx;
    let dx0 = dx - j * dxx;
    let dy0 = dy - i * dxx;
    var s: Span;
    s.p[0] = p00;
    s.p[1] = p00 + dx0;
    s.p[2] = p00 + dy0;
    s.p[3] = p00 + dx0 + dy0 + dxx;
    s.ok = vec4<bool>(true);
    // the lane's own point, exactly
    let me = u32(i) + 2u * u32(j);
    s.p[me] = p;
    let c = span_sample(s, me);
    return encode(c.rgb + GROUND * (1.0 - c.a));
}

// the sky behind the mesh: drawn last at the far plane, where nothing was drawn
@vertex
fn vs_sky(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 1.0, 1.0);
}

@fragment
fn fs_sky(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    return encode(sky(frag.y));
}
