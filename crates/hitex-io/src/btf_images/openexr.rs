//! OpenEXR images of a set: decoded to linear sRGB primaries (RGB, XYZ or
//! grey channels, clamped to half-float range) and written as half floats.

use super::*;

/// Linear sRGB (D65) from CIE XYZ.
pub(super) const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240_454_2, -1.537_138_5, -0.498_531_4],
    [-0.969_266_0, 1.876_010_8, 0.041_556_0],
    [0.055_643_4, -0.204_025_9, 1.057_225_2],
];

/// Rec. 709 / sRGB primaries and D65 white, as `chromaticities` records them.
pub(super) const REC709: [[f64; 2]; 4] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]];

pub(super) fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

pub(super) fn inverse3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let c = |r: usize, k: usize| {
        let (r1, r2, k1, k2) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    if det.abs() < 1e-12 || !det.is_finite() {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (k, v) in row.iter_mut().enumerate() {
            *v = c(k, r) / det;
        }
    }
    Some(inv)
}

/// The RGB → XYZ matrix of primaries and a white point (xy chromaticities),
/// adapted to D65: the columns are the primaries' (x, y, 1 − x − y) scaled
/// so that RGB (1, 1, 1) is the white of luminance 1 (a primary may have
/// y = 0, as the XYZ-as-RGB convention's blue (0, 0) has), then a Bradford
/// adaptation from that white to D65, the white of linear sRGB.
pub(super) fn rgb_to_xyz(c: &[[f64; 2]; 4]) -> Option<[[f64; 3]; 3]> {
    let col = |p: [f64; 2]| [p[0], p[1], 1.0 - p[0] - p[1]];
    let (r, g, b) = (col(c[0]), col(c[1]), col(c[2]));
    if c[3][1] <= 0.0 {
        return None;
    }
    let xyz_of = |p: [f64; 2]| [p[0] / p[1], 1.0, (1.0 - p[0] - p[1]) / p[1]];
    let w = xyz_of(c[3]);
    let p = [[r[0], g[0], b[0]], [r[1], g[1], b[1]], [r[2], g[2], b[2]]];
    let inv = inverse3(&p)?;
    let s: Vec<f64> = (0..3).map(|i| (0..3).map(|k| inv[i][k] * w[k]).sum()).collect();
    let m = [
        [p[0][0] * s[0], p[0][1] * s[1], p[0][2] * s[2]],
        [p[1][0] * s[0], p[1][1] * s[1], p[1][2] * s[2]],
        [p[2][0] * s[0], p[2][1] * s[1], p[2][2] * s[2]],
    ];
    // Bradford cone response; scale from the file's white to D65
    const BRADFORD: [[f64; 3]; 3] = [[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]];
    let d65 = xyz_of(REC709[3]);
    let cone = |v: [f64; 3]| -> [f64; 3] { [0, 1, 2].map(|i| (0..3).map(|k| BRADFORD[i][k] * v[k]).sum()) };
    let (src, dst) = (cone(w), cone(d65));
    if src.iter().any(|&v| v.abs() < 1e-12) {
        return None;
    }
    let diag = [[dst[0] / src[0], 0.0, 0.0], [0.0, dst[1] / src[1], 0.0], [0.0, 0.0, dst[2] / src[2]]];
    let adapt = mul3(&inverse3(&BRADFORD)?, &mul3(&diag, &BRADFORD));
    Some(mul3(&adapt, &m))
}

/// A decoded EXR image: linear RGB (sRGB primaries) and the values clamped.
pub(super) struct ExrImage {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) rgb: Vec<f32>,
    pub(super) clamped: u64,
}

/// Decodes an OpenEXR image to linear RGB with sRGB primaries, checking the
/// declared size before decoding; see the module documentation for the
/// channels read and the clamping.
pub(super) fn decode_exr(bytes: &[u8], path: &Path) -> Result<ExrImage, IoError> {
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| fmt(format!("not a readable OpenEXR file: {e}")))?;
    let Some(header) = meta.headers.iter().find(|h| !h.deep) else {
        return Err(fmt("the EXR file holds deep data only; a BTF image is a flat image".into()));
    };
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    let side = hitex_core::texture::image::MAX_IMAGE_SIDE as usize;
    if w == 0 || h == 0 || w > side || h > side {
        return Err(fmt(format!("declared size {w}x{h} is outside 1..={side} per side")));
    }
    let names: Vec<String> = header.channels.list.iter().map(|c| c.name.to_string()).collect();
    let short = |n: &str| n.rsplit('.').next().unwrap_or(n).to_string();
    let find = |want: &str| names.iter().position(|n| short(n) == want);
    enum Model {
        Rgb([usize; 3]),
        Xyz([usize; 3]),
        Grey(usize),
    }
    let model = match (find("R"), find("G"), find("B"), find("X"), find("Y"), find("Z")) {
        (Some(r), Some(g), Some(b), ..) => Model::Rgb([r, g, b]),
        (.., Some(x), Some(y), Some(z)) => Model::Xyz([x, y, z]),
        (None, None, None, None, Some(y), None) => Model::Grey(y),
        _ => {
            return Err(fmt(format!(
                "the EXR channels are {}; a BTF image needs R, G and B, or X, Y and Z, or Y alone",
                if names.is_empty() { "none".to_string() } else { names.join(", ") }
            )));
        }
    };
    let used: Vec<usize> = match model {
        Model::Rgb(c) | Model::Xyz(c) => c.to_vec(),
        Model::Grey(y) => vec![y],
    };
    for &c in &used {
        let ch = &header.channels.list[c];
        if (ch.sampling.0, ch.sampling.1) != (1, 1) {
            return Err(fmt(format!(
                "channel {} is subsampled {}x{}; BTF images need every channel at full resolution",
                names[c], ch.sampling.0, ch.sampling.1
            )));
        }
    }
    // every channel of the layer is decoded (2 or 4 bytes a sample), then
    // three f32 planes and the RGB result: 24 bytes a texel
    let stored: u64 = header
        .channels
        .list
        .iter()
        .map(|c| match c.sample_type {
            exr::meta::attribute::SampleType::F16 => 2u64,
            _ => 4,
        })
        .sum();
    let claim = crate::limits::product(&[w as u64, h as u64, stored + 24]);
    crate::limits::check_cap(&format!("an EXR image of {w}x{h} texels in {} channels", names.len()), claim)
        .map_err(|e| fmt(e.to_string()))?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| fmt(format!("cannot decode the EXR image: {e}")))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    let list = &layer.channel_data.list;
    let values = |want: &str| -> Result<Vec<f32>, IoError> {
        let ch = list
            .iter()
            .find(|c| short(&c.name.to_string()) == want)
            .ok_or_else(|| fmt(format!("channel {want} is declared but not decoded")))?;
        let v: Vec<f32> = match &ch.sample_data {
            FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
            FlatSamples::F32(v) => v.clone(),
            FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
        };
        if v.len() != w * h {
            return Err(fmt(format!("channel {want} holds {} samples; {w}x{h} needs {}", v.len(), w * h)));
        }
        Ok(v)
    };
    // matrix to linear sRGB, if any
    let (chans, matrix): ([Vec<f32>; 3], Option<[[f64; 3]; 3]>) = match model {
        Model::Rgb(_) => {
            let m = match image.attributes.chromaticities {
                Some(c) => {
                    let got = [
                        [c.red.0 as f64, c.red.1 as f64],
                        [c.green.0 as f64, c.green.1 as f64],
                        [c.blue.0 as f64, c.blue.1 as f64],
                        [c.white.0 as f64, c.white.1 as f64],
                    ];
                    let same = got.iter().flatten().zip(REC709.iter().flatten()).all(|(a, b)| (a - b).abs() < 1e-3);
                    if same {
                        None
                    } else {
                        let m = rgb_to_xyz(&got)
                            .filter(|m| m.iter().flatten().all(|v| v.is_finite()))
                            .ok_or_else(|| fmt(format!("the chromaticities attribute {got:?} is degenerate")))?;
                        Some(mul3(&XYZ_TO_SRGB, &m))
                    }
                }
                None => None,
            };
            ([values("R")?, values("G")?, values("B")?], m)
        }
        Model::Xyz(_) => ([values("X")?, values("Y")?, values("Z")?], Some(XYZ_TO_SRGB)),
        Model::Grey(_) => {
            let y = values("Y")?;
            ([y.clone(), y.clone(), y], None)
        }
    };
    let mut rgb = Vec::with_capacity(w * h * 3);
    let mut clamped = 0u64;
    for ((&r, &g), &b) in chans[0].iter().zip(&chans[1]).zip(&chans[2]) {
        let c = [r, g, b];
        let c = match &matrix {
            Some(m) => {
                let f = |r: usize| (0..3).map(|k| m[r][k] * c[k] as f64).sum::<f64>() as f32;
                [f(0), f(1), f(2)]
            }
            None => c,
        };
        for v in c {
            let ok = (0.0..=65504.0).contains(&v);
            clamped += !ok as u64;
            rgb.push(if v > 0.0 { v.min(65504.0) } else { 0.0 });
        }
    }
    Ok(ExrImage { width: w as u32, height: h as u32, rgb, clamped })
}

/// Decodes an OpenEXR image as a BTF image set reads it: width, height and
/// linear RGB with sRGB primaries (three values a texel, rows top to
/// bottom), finite and in [0, 65504], and the number of values clamped
/// into that range. See the module documentation for the channels read.
pub fn decode_exr_image(bytes: &[u8], path: &Path) -> Result<(u32, u32, Vec<f32>, u64), IoError> {
    let img = decode_exr(bytes, path)?;
    Ok((img.width, img.height, img.rgb, img.clamped))
}

/// One image of `btf` as an OpenEXR file in memory: half-float linear RGB.
pub(super) fn exr_bytes(btf: &Btf, view: usize, light: usize) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    let (w, h) = (btf.width() as usize, btf.height() as usize);
    let half: Vec<u16> = match btf.image_half(view, light) {
        Some(h) => h.to_vec(),
        None => btf.image(view, light).iter().map(|&c| half_bits(srgb_to_linear(c as f32 / 255.0))).collect(),
    };
    let channel = |name: &str, k: usize| {
        let v: Vec<f16> = half.iter().skip(k).step_by(3).map(|&b| f16::from_bits(b)).collect();
        AnyChannel::new(name, FlatSamples::F16(v))
    };
    let channels = AnyChannels::sort(vec![channel("R", 0), channel("G", 1), channel("B", 2)].into());
    let layer = Layer::new((w, h), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, channels);
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().non_parallel().to_buffered(&mut out).map_err(|e| e.to_string())?;
    Ok(out.into_inner())
}
