// BTF fragment program. Twin of `src/cpu/btf.rs` (and of
// `hitex_core::btf::{frames, grid, layout}`): same inputs, same steps, same order.
//
// The host prepends the layout's constants (FILTERED, TILE_X, TILE_Y,
// DEPTH_AXIS, DEPTH_REPEAT) and keeps the `//#if D3` or the `//#else`
// branch: the codebook is a 2-D or a 3-D texture.

struct Frame {
    view_proj: mat4x4<f32>,
    camera: vec4<f32>,
    light: vec4<f32>,       // xyz position, w exposure
    background: vec4<f32>,
    tex_size: vec4<f32>,    // codebook width, height, layers
    sizes: vec4<u32>,       // index width, height, θ count, φ count
    tile: vec4<u32>,        // tile width, height, tiles per row; tone map
    strides: array<vec4<u32>, 2>,
    theta: array<vec4<f32>, 16>, // polar angles in degrees
    mip: vec4<u32>,         // index-map MIP levels (1: none); PCA components + 1 (0: raw)
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var index_map: texture_2d<u32>;
//#if D3
@group(0) @binding(2) var codebook: texture_3d<f32>;
//#else
@group(0) @binding(2) var codebook: texture_2d<f32>;
//#endif
@group(0) @binding(3) var filt: sampler;
// a local-PCA codebook's per-texel half: per sample texel (mip.y + 3) / 4
// texels, the cluster in the first channel, then the coefficients
@group(0) @binding(4) var pca_coefs: texture_2d<f32>;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent_u: vec3<f32>,
    @location(3) tangent_v: vec3<f32>,
    @location(4) uv: vec2<f32>,
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) tangent_u: vec3<f32>,
    @location(3) tangent_v: vec3<f32>,
    @location(4) uv: vec2<f32>,
}

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    o.world = v.position;
    o.normal = v.normal;
    o.tangent_u = v.tangent_u;
    o.tangent_v = v.tangent_v;
    o.uv = v.uv;
    return o;
}

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;

fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if (l > 0.0) {
        return v / l;
    }
    return fallback;
}

// ---- per-pixel angles (frames.rs) ----

fn angles(p: vec3<f32>, n: vec3<f32>, u: vec3<f32>, v: vec3<f32>, pc: vec3<f32>) -> vec2<f32> {
    let c = pc - p;
    let len = length(c);
    if (!(len > 0.0)) {
        return vec2<f32>(0.0, 0.0);
    }
    let c1 = c / len;
    // θ = acos(C′·N)
    let s = clamp(dot(c1, n), -1.0, 1.0);
    let theta = acos(s);
    // R = N × C′, φ = acos(U·R′) − π/2
    let r = cross(n, c1);
    let rl = length(r);
    if (!(rl > 1e-7)) {
        return vec2<f32>(theta, 0.0);
    }
    let t = clamp(dot(u, r / rl), -1.0, 1.0);
    var phi = acos(t) - PI * 0.5;
    // correction with V: sense of rotation, then the far half circle
    if (dot(cross(n, u), v) < 0.0) {
        phi = -phi;
    }
    if (dot(c1, u) < 0.0) {
        phi = PI - phi;
    }
    return vec2<f32>(theta, phi - TAU * floor(phi / TAU));
}

// ---- neighbouring samples (grid.rs) ----

struct Lerp {
    i0: u32,
    i1: u32,
    t: f32,
    coord: f32,
}

fn theta_at(i: u32) -> f32 {
    return frame.theta[i / 4u][i % 4u];
}

fn lerp_theta(theta: f32) -> Lerp {
    let deg = degrees(theta);
    let n = frame.sizes.z;
    if (n == 1u || deg <= theta_at(0u)) {
        return Lerp(0u, 0u, 0.0, 0.0);
    }
    if (deg >= theta_at(n - 1u)) {
        return Lerp(n - 1u, n - 1u, 0.0, f32(n - 1u));
    }
    // first ring above deg
    var i1 = 1u;
    for (var i = 1u; i < n - 1u; i = i + 1u) {
        if (theta_at(i) <= deg) {
            i1 = i + 1u;
        }
    }
    let i0 = i1 - 1u;
    let t = clamp((deg - theta_at(i0)) / (theta_at(i1) - theta_at(i0)), 0.0, 1.0);
    return Lerp(i0, i1, t, f32(i0) + t);
}

fn lerp_phi(phi: f32) -> Lerp {
    let nu = frame.sizes.w;
    let n = f32(nu);
    var x = phi / TAU * n;
    x = x - n * floor(x / n);
    if (x >= n) {
        x = 0.0;
    }
    let i0 = min(u32(floor(x)), nu - 1u);
    let t = clamp(x - f32(i0), 0.0, 1.0);
    return Lerp(i0, (i0 + 1u) % nu, t, x);
}

// ---- codebook reads through the layout (layout.rs, Codebook::corner) ----

fn stride(a: u32) -> u32 {
    return frame.strides[a / 4u][a % 4u];
}

fn read_texel(x: f32, y: f32) -> vec3<f32> {
//#if D3
    return vec3<f32>(0.0);
//#else
    return textureLoad(codebook, vec2<i32>(i32(x), i32(y)), 0).rgb;
//#endif
}

fn read_filtered(x: f32, y: f32, z: f32) -> vec3<f32> {
    let size = frame.tex_size;
//#if D3
    return textureSampleLevel(codebook, filt, vec3<f32>(x / size.x, y / size.y, z / size.z), 0.0).rgb;
//#else
    return textureSampleLevel(codebook, filt, vec2<f32>(x / size.x, y / size.y), 0.0).rgb;
//#endif
}

fn fetch_corner(su: u32, sv: u32, lerps: array<Lerp, 4>) -> vec3<f32> {
    var l = lerps;
    // the angular axes the shader walks, each with two neighbours
    let nwalk = 4u - countOneBits(FILTERED);
    var acc = vec3<f32>(0.0);
    for (var combo = 0u; combo < (1u << nwalk); combo = combo + 1u) {
        // discrete index per axis and the combination's weight
        var idx = array<u32, 6>(su, sv, 0u, 0u, 0u, 0u);
        var crd = array<f32, 6>(f32(su), f32(sv), l[0].coord, l[1].coord, l[2].coord, l[3].coord);
        var w = 1.0;
        var bit = 0u;
        for (var a = 2u; a < 6u; a = a + 1u) {
            if ((FILTERED & (1u << a)) == 0u) {
                let ax = l[a - 2u];
                if ((combo & (1u << bit)) != 0u) {
                    idx[a] = ax.i1;
                    w = w * ax.t;
                } else {
                    idx[a] = ax.i0;
                    w = w * (1.0 - ax.t);
                }
                crd[a] = f32(idx[a]);
                bit = bit + 1u;
            }
        }
        // tile origin
        var k = 0u;
        for (var a = 0u; a < 6u; a = a + 1u) {
            k = k + idx[a] * stride(a);
        }
        let ox = f32((k % frame.tile.z) * frame.tile.x);
        let oy = f32((k / frame.tile.z) * frame.tile.y);
        let x = ox + crd[TILE_X] + 0.5;
        let y = oy + crd[TILE_Y] + 0.5;
        var value: vec3<f32>;
        if (FILTERED == 0u) {
            value = read_texel(x, y);
        } else if (DEPTH_AXIS == 6u) {
            value = read_filtered(x, y, 0.5);
        } else {
            value = read_filtered(x, y, crd[min(DEPTH_AXIS, 5u)] + 0.5);
        }
        acc = acc + value * w;
    }
    return acc;
}

// ---- index map (cpu/btf.rs, index_taps) ----

struct Taps {
    i0: u32,
    i1: u32,
    f: f32,
}

fn index_taps(t_in: f32, size: u32) -> Taps {
    let t = clamp(t_in, -1.0e6, 1.0e6);
    let x = t * f32(size) - 0.5;
    let f0 = floor(x);
    let n = i32(size);
    let i0 = i32(f0);
    let a = ((i0 % n) + n) % n;
    let b = (((i0 + 1) % n) + n) % n;
    return Taps(u32(a), u32(b), x - f0);
}

// ---- output ----


// Twin of hitex_core::texture::ToneMap::apply: TONE_NONE, TONE_REINHARD, TONE_ACES (fit).
fn tone_map(c: vec3<f32>, mode: u32) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0e4));
    if mode == TONE_REINHARD {
        return x / (vec3<f32>(1.0) + x);
    }
    if mode == TONE_ACES {
        return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
    }
    return x;
}

// Where MIP level `level` of the index map lies in the index atlas and its
// size: level 0 at the origin, every coarser level stacked in a column to its
// right. One atlas read at texture level 0, because llvmpipe resolves the level
// of a texel fetch once per SIMD group (see the textured shader).
fn index_level_rect(level: u32) -> vec4<u32> {
    let w = frame.sizes.x;
    let h = frame.sizes.y;
    if (level == 0u) {
        return vec4<u32>(0u, 0u, w, h);
    }
    var oy = 0u;
    for (var j = 1u; j < level; j = j + 1u) {
        oy = oy + max(1u, h >> j);
    }
    return vec4<u32>(w, oy, max(1u, w >> level), max(1u, h >> level));
}

// The four index texels of one MIP level around T, through the layout's
// reads, bilinearly weighted (4 index reads).
fn index_level(uv: vec2<f32>, level: u32, l: array<Lerp, 4>) -> vec3<f32> {
    let r = index_level_rect(level);
    let tx = index_taps(uv.x, r.z);
    let ty = index_taps(uv.y, r.w);
    let x0 = r.x + tx.i0;
    let x1 = r.x + tx.i1;
    let y0 = r.y + ty.i0;
    let y1 = r.y + ty.i1;
    let e00 = textureLoad(index_map, vec2<u32>(x0, y0), 0).xy;
    let e10 = textureLoad(index_map, vec2<u32>(x1, y0), 0).xy;
    let e01 = textureLoad(index_map, vec2<u32>(x0, y1), 0).xy;
    let e11 = textureLoad(index_map, vec2<u32>(x1, y1), 0).xy;
    let w = array<f32, 4>((1.0 - tx.f) * (1.0 - ty.f), tx.f * (1.0 - ty.f), (1.0 - tx.f) * ty.f, tx.f * ty.f);
    if (frame.mip.y > 0u) {
        return pca_value(array<vec2<u32>, 4>(e00, e10, e01, e11), w, l);
    }
    // hexa-linear over the angles through the layout's reads
    var acc = fetch_corner(e00.x, e00.y, l) * w[0];
    acc = acc + fetch_corner(e10.x, e10.y, l) * w[1];
    acc = acc + fetch_corner(e01.x, e01.y, l) * w[2];
    acc = acc + fetch_corner(e11.x, e11.y, l) * w[3];
    return acc;
}

// ---- local PCA (cpu/btf.rs, pca_pixel) ----

fn pca_slot(e: vec2<u32>, j: u32) -> f32 {
    let per = (frame.mip.y + 3u) / 4u;
    let t = textureLoad(pca_coefs, vec2<u32>(e.x * per + j / 4u, e.y), 0);
    return t[j % 4u];
}

// Per cluster among the four index texels, in order of first appearance:
// their coefficients blended by their weights, then each basis image of the
// cluster (sample texel (j, cluster) of the basis codebook) read once.
fn pca_value(e: array<vec2<u32>, 4>, w: array<f32, 4>, l: array<Lerp, 4>) -> vec3<f32> {
    let slots = frame.mip.y;
    var cl: array<u32, 4>;
    for (var q = 0u; q < 4u; q = q + 1u) {
        cl[q] = u32(pca_slot(e[q], 0u) + 0.5);
    }
    var done = array<bool, 4>(false, false, false, false);
    var acc = vec3<f32>(0.0);
    for (var q = 0u; q < 4u; q = q + 1u) {
        if (done[q]) {
            continue;
        }
        let c = cl[q];
        var bw: array<f32, 16>;
        for (var r = q; r < 4u; r = r + 1u) {
            if (!done[r] && cl[r] == c) {
                done[r] = true;
                bw[0] = bw[0] + w[r];
                for (var j = 1u; j < slots; j = j + 1u) {
                    bw[j] = bw[j] + w[r] * pca_slot(e[r], j);
                }
            }
        }
        for (var j = 0u; j < slots; j = j + 1u) {
            acc = acc + fetch_corner(j, c, l) * bw[j];
        }
    }
    return acc;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // the level of detail (seed 001, eq. 2, the Vulkan rho) in uniform control flow
    let texels = vec2<f32>(f32(frame.sizes.x), f32(frame.sizes.y));
    let dx = dpdxFine(in.uv) * texels;
    let dy = dpdyFine(in.uv) * texels;
    let rho = sqrt(max(dot(dx, dx), dot(dy, dy)));
    let p = in.world;
    let cam = frame.camera.xyz;
    let light = frame.light.xyz;
    // per-pixel frame; the normal faces the viewer
    var n = normalize_or(in.normal, vec3<f32>(0.0, 0.0, 1.0));
    let u = normalize_or(in.tangent_u, vec3<f32>(1.0, 0.0, 0.0));
    let v = normalize_or(in.tangent_v, vec3<f32>(0.0, 1.0, 0.0));
    if (dot(n, cam - p) < 0.0) {
        n = -n;
    }
    // light below the surface: no light
    if (dot(n, light - p) <= 0.0) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    // view and light angles, their neighbouring samples
    let ac = angles(p, n, u, v, cam);
    let al = angles(p, n, u, v, light);
    let l = array<Lerp, 4>(lerp_theta(ac.x), lerp_phi(ac.y), lerp_theta(al.x), lerp_phi(al.y));
    // index map at the level pair of the footprint, blended trilinearly
    var acc: vec3<f32>;
    if (frame.mip.x > 1u) {
        var lod = 0.0;
        if (rho > 0.0 && rho <= 3.0e38) {
            lod = clamp(log2(rho), 0.0, f32(frame.mip.x - 1u));
        }
        let l0 = floor(lod);
        let t = lod - l0;
        let k = u32(l0);
        acc = index_level(in.uv, k, l);
        if (t > 0.0) {
            acc = acc * (1.0 - t) + index_level(in.uv, min(k + 1u, frame.mip.x - 1u), l) * t;
        }
    } else {
        acc = index_level(in.uv, 0u, l);
    }
    let c = tone_map(acc * frame.light.w, frame.tile.w);
    return vec4<f32>(linear_to_srgb(c.x), linear_to_srgb(c.y), linear_to_srgb(c.z), 1.0);
}
