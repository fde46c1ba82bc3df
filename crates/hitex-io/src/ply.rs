//! PLY (Stanford polygon files), ASCII and binary little- or big-endian: the
//! form in which scanners and point-cloud tools (CloudCompare, MeshLab,
//! Open3D) write meshes and point clouds. A file with faces is read as a mesh
//! (each face a fan of triangles), one without as its vertices. Vertices need
//! `x`, `y` and `z` properties of any numeric type; faces a list property
//! `vertex_indices` (or `vertex_index`). Other elements and properties
//! (normals, colours, edges, materials) are read past. Claimed counts are
//! checked against the bytes that follow the header before anything is
//! allocated; every error names the element and the record (and, in ASCII,
//! the line) or the header line.

use crate::stl::{ReferenceData, Triangle};
use crate::{DataError, IoError};
use std::path::Path;

/// Longest header read, in bytes.
const MAX_HEADER: usize = 1 << 20;

/// Reads a PLY file: its faces as triangles, or its vertices as points.
pub fn load_ply(path: &Path) -> Result<ReferenceData, IoError> {
    let bytes = read(path)?;
    parse_ply(&bytes).map_err(|e| e.in_file(path))
}

/// Reads the vertices of a PLY file as points (a scan's mesh measured at
/// its vertices), whether or not it has faces; the faces are checked all the same.
pub fn load_ply_vertices(path: &Path) -> Result<Vec<[f64; 3]>, IoError> {
    let bytes = read(path)?;
    parse_parts(&bytes).map(|(p, _)| p).map_err(|message| IoError::Format { path: path.to_path_buf(), message })
}

/// The file's bytes, when what it can hold fits the memory cap.
fn read(path: &Path) -> Result<Vec<u8>, IoError> {
    let read = |source| IoError::Read { path: path.to_path_buf(), source };
    let meta = std::fs::metadata(path).map_err(read)?;
    // a binary face of three 32-bit indices (13 bytes) becomes one 72-byte
    // triangle; a binary vertex of three floats (12 bytes) a 24-byte point
    crate::limits::check_cap("reading this PLY file", Some(meta.len().saturating_mul(6)))
        .map_err(|e| IoError::Format { path: path.to_path_buf(), message: e.to_string() })?;
    std::fs::read(path).map_err(read)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Prop {
    One(Scalar),
    /// A list: the type of its length, the type of its items.
    List(Scalar, Scalar),
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<(String, Prop)>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// The header's elements, the body's format and where the body begins.
fn header(bytes: &[u8]) -> Result<(Format, Vec<Element>, usize), String> {
    let head = &bytes[..bytes.len().min(MAX_HEADER)];
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0;
    let mut number = 0;
    loop {
        number += 1;
        let Some(len) = head[pos..].iter().position(|&b| b == b'\n') else {
            return Err(if bytes.len() > MAX_HEADER {
                format!("no `end_header` line in the first {MAX_HEADER} bytes")
            } else {
                "the header ends without an `end_header` line".into()
            });
        };
        let line = String::from_utf8_lossy(&head[pos..pos + len]);
        pos += len + 1;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        if number == 1 {
            if words != ["ply"] {
                return Err("not a PLY file: the first line is not `ply`".into());
            }
            continue;
        }
        let bad = |what: &str| format!("header line {number} (`{}`): {what}", line.trim());
        match words.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match words.get(1..) {
                    Some(["ascii", "1.0"]) => Format::Ascii,
                    Some(["binary_little_endian", "1.0"]) => Format::Little,
                    Some(["binary_big_endian", "1.0"]) => Format::Big,
                    _ => {
                        return Err(bad(
                            "the format must be ascii, binary_little_endian or binary_big_endian, version 1.0",
                        ));
                    }
                });
            }
            Some("element") => {
                let (Some(name), Some(count), None) = (words.get(1), words.get(2), words.get(3)) else {
                    return Err(bad("an element is `element NAME COUNT`"));
                };
                let count = count.parse::<u64>().map_err(|_| bad("the count is not a whole number"))?;
                elements.push(Element { name: name.to_string(), count, props: Vec::new() });
            }
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(bad("a property before any element"));
                };
                let ty = |w: Option<&&str>| w.and_then(|w| Scalar::parse(w));
                let (prop, name) = if words.get(1) == Some(&"list") {
                    match (ty(words.get(2)), ty(words.get(3)), words.get(4), words.get(5)) {
                        (Some(n), Some(item), Some(name), None) => {
                            if matches!(n, Scalar::F32 | Scalar::F64) {
                                return Err(bad("a list's length must have an integer type"));
                            }
                            (Prop::List(n, item), name)
                        }
                        _ => return Err(bad("a list property is `property list COUNT_TYPE ITEM_TYPE NAME`")),
                    }
                } else {
                    match (ty(words.get(1)), words.get(2), words.get(3)) {
                        (Some(t), Some(name), None) => (Prop::One(t), name),
                        _ => {
                            return Err(bad(
                                "a property is `property TYPE NAME` with a PLY type (float, int, uchar, …)",
                            ));
                        }
                    }
                };
                el.props.push((name.to_string(), prop));
            }
            Some("end_header") => break,
            Some(_) => return Err(bad("not a PLY header line (is the `end_header` line missing?)")),
        }
    }
    let format = format.ok_or("the header has no `format` line")?;
    Ok((format, elements, pos))
}

/// The body, read value by value.
struct Body<'a> {
    format: Format,
    bytes: &'a [u8],
    pos: usize,
    /// Line of the ASCII cursor (1-based, in the whole file).
    line: usize,
}

impl Body<'_> {
    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// The next value, or a message saying what is wrong with it.
    /// Moves an ASCII cursor past white space (to the next record's line).
    fn skip_space(&mut self) {
        if self.format == Format::Ascii {
            while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
                self.line += (self.bytes[self.pos] == b'\n') as usize;
                self.pos += 1;
            }
        }
    }

    fn value(&mut self, s: Scalar) -> Result<f64, String> {
        if self.format == Format::Ascii {
            self.skip_space();
            let start = self.pos;
            while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if start == self.pos {
                return Err("the file ends".into());
            }
            let word = String::from_utf8_lossy(&self.bytes[start..self.pos]);
            let x: f64 = word.parse().map_err(|_| format!("`{word}` is not a number"))?;
            if !matches!(s, Scalar::F32 | Scalar::F64) && x.fract() != 0.0 {
                return Err(format!("`{word}` is not a whole number"));
            }
            return Ok(x);
        }
        let n = s.size();
        let Some(b) = self.bytes.get(self.pos..self.pos + n) else {
            return Err("the file ends".into());
        };
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.format == Format::Big {
            a[..n].reverse();
        }
        Ok(match s {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
}

/// Parses PLY bytes: the faces as triangles when the file has any, else the
/// vertices as points.
pub fn parse_ply(bytes: &[u8]) -> Result<ReferenceData, DataError> {
    ply(bytes).map_err(DataError::from)
}

fn ply(bytes: &[u8]) -> Result<ReferenceData, String> {
    let (points, tris) = parse_parts(bytes)?;
    Ok(match tris {
        Some(t) => ReferenceData::Mesh(t),
        None => ReferenceData::Points(points),
    })
}

/// The vertices, and the faces' triangles when the file has faces.
#[allow(clippy::type_complexity)]
fn parse_parts(bytes: &[u8]) -> Result<(Vec<[f64; 3]>, Option<Vec<Triangle>>), String> {
    let (format, elements, start) = header(bytes)?;
    let header_lines = bytes[..start].iter().filter(|&&b| b == b'\n').count();
    let mut body = Body { format, bytes, pos: start, line: header_lines + 1 };
    let vertex = elements.iter().position(|e| e.name == "vertex").ok_or("the header declares no `vertex` element")?;
    let axis = |name: &str| -> Result<usize, String> {
        elements[vertex]
            .props
            .iter()
            .position(|(n, p)| n == name && matches!(p, Prop::One(_)))
            .ok_or(format!("the vertex element has no `{name}` property"))
    };
    let xyz = [axis("x")?, axis("y")?, axis("z")?];
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut faces: Vec<(u64, Vec<u64>)> = Vec::new();
    let mut has_faces = false;
    for el in &elements {
        // every record takes at least a byte a value (ASCII: a character
        // and a separator, less one at the end) or its fixed part (binary)
        let least: usize = el
            .props
            .iter()
            .map(|(_, p)| match (format, p) {
                (Format::Ascii, _) => 1,
                (_, Prop::One(s)) => s.size(),
                (_, Prop::List(n, _)) => n.size(),
            })
            .sum();
        if (el.count as u128) * (least as u128) > body.left() as u128 + 1 {
            return Err(format!(
                "the header claims {} {} records (at least {} bytes), but {} bytes follow it",
                el.count,
                el.name,
                el.count as u128 * least as u128,
                body.left()
            ));
        }
        let is_vertex = el.name == "vertex";
        let list = (el.name == "face")
            .then(|| {
                el.props
                    .iter()
                    .position(|(n, p)| (n == "vertex_indices" || n == "vertex_index") && matches!(p, Prop::List(..)))
            })
            .flatten();
        if el.name == "face" && el.count > 0 {
            has_faces = true;
            if list.is_none() {
                return Err("the face element has no `vertex_indices` list".into());
            }
        }
        if is_vertex {
            points.reserve(el.count as usize);
        }
        if el.props.is_empty() {
            // records of nothing take no bytes
            continue;
        }
        for r in 0..el.count {
            body.skip_space();
            let line = body.line;
            let at = |m: String| {
                if format == Format::Ascii {
                    format!("{} {r} (line {line}): {m}", el.name)
                } else {
                    format!("{} {r}: {m}", el.name)
                }
            };
            let mut p = [0.0f64; 3];
            for (k, (_, prop)) in el.props.iter().enumerate() {
                match *prop {
                    Prop::One(s) => {
                        let x = body.value(s).map_err(at)?;
                        if is_vertex && let Some(axis) = xyz.iter().position(|&i| i == k) {
                            if !x.is_finite() {
                                return Err(at(format!("coordinate {} is {x}", ["x", "y", "z"][axis])));
                            }
                            p[axis] = x;
                        }
                    }
                    Prop::List(n, item) => {
                        let len = body.value(n).map_err(at)?;
                        if len < 0.0 {
                            return Err(at(format!("a list of {len} items")));
                        }
                        let least = if format == Format::Ascii { 1 } else { item.size() };
                        if len * least as f64 > body.left() as f64 + 1.0 {
                            return Err(at(format!("a list of {len} items, longer than the rest of the file")));
                        }
                        let mut items = Vec::with_capacity(if Some(k) == list { len as usize } else { 0 });
                        for _ in 0..len as u64 {
                            let x = body.value(item).map_err(at)?;
                            if Some(k) == list {
                                if !(x >= 0.0 && x.fract() == 0.0) {
                                    return Err(at(format!("vertex index {x} is not a whole number ≥ 0")));
                                }
                                items.push(x as u64);
                            }
                        }
                        if Some(k) == list {
                            if items.len() < 3 {
                                return Err(at(format!(
                                    "a face of {} vertices (three or more make a face)",
                                    items.len()
                                )));
                            }
                            faces.push((r, items));
                        }
                    }
                }
            }
            if is_vertex {
                points.push(p);
            }
        }
    }
    if points.is_empty() {
        return Err("no vertices".into());
    }
    if !has_faces {
        return Ok((points, None));
    }
    // a face of n vertices is n − 2 triangles of 72 bytes: long faces of
    // short ASCII indices could ask for far more than the file's size
    let count: u64 = faces.iter().map(|(_, f)| f.len() as u64 - 2).sum();
    crate::limits::check_cap("the triangles of this PLY file", count.checked_mul(72)).map_err(|e| e.to_string())?;
    let mut tris: Vec<Triangle> = Vec::with_capacity(count as usize);
    for (r, face) in &faces {
        let get = |i: u64| {
            points
                .get(i as usize)
                .copied()
                .ok_or(format!("face {r}: vertex index {i} is past the {} vertices", points.len()))
        };
        let a = get(face[0])?;
        for w in face[1..].windows(2) {
            tris.push([a, get(w[0])?, get(w[1])?]);
        }
    }
    Ok((points, Some(tris)))
}

/// Writes triangles as binary little-endian PLY (three vertices a triangle,
/// as f32; for tests and round trips).
pub fn to_binary_ply(tris: &[Triangle]) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment hitex\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        3 * tris.len(),
        tris.len()
    )
    .into_bytes();
    for p in tris.iter().flatten() {
        for x in p {
            out.extend((*x as f32).to_le_bytes());
        }
    }
    for k in 0..tris.len() as u32 {
        out.push(3);
        for i in 0..3 {
            out.extend((3 * k + i).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: &str = "ply\nformat ascii 1.0\ncomment a unit square\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0.5 9\n4 0 1 2 3\n";

    /// The square of `SQUARE` in a binary body of the given byte order.
    fn binary(big: bool) -> Vec<u8> {
        let name = if big { "binary_big_endian" } else { "binary_little_endian" };
        let mut b = format!(
            "ply\nformat {name} 1.0\nelement vertex 4\nproperty double x\nproperty float y\nproperty float z\nproperty uchar red\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nelement face 1\nproperty list uchar uint vertex_indices\nproperty list ushort short extra\nend_header\n"
        )
        .into_bytes();
        let f = |x: f32| if big { x.to_be_bytes() } else { x.to_le_bytes() };
        for (x, y, z) in [(0.0f64, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.5)] {
            b.extend(if big { x.to_be_bytes() } else { x.to_le_bytes() });
            b.extend(f(y));
            b.extend(f(z));
            b.push(7);
        }
        let i = |x: u32| if big { x.to_be_bytes() } else { x.to_le_bytes() };
        b.extend(i(0));
        b.extend(i(1));
        b.push(4);
        for k in 0..4 {
            b.extend(i(k));
        }
        b.extend(if big { 1u16.to_be_bytes() } else { 1u16.to_le_bytes() });
        b.extend([0, 5]);
        b
    }

    fn square() -> Vec<Triangle> {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.5]];
        vec![[p[0], p[1], p[2]], [p[0], p[2], p[3]]]
    }

    #[test]
    fn ascii_and_binary_faces_read_as_the_same_triangles() {
        assert_eq!(parse_ply(SQUARE.as_bytes()), Ok(ReferenceData::Mesh(square())));
        assert_eq!(parse_ply(&binary(false)), Ok(ReferenceData::Mesh(square())));
        assert_eq!(parse_ply(&binary(true)), Ok(ReferenceData::Mesh(square())));
        // CRLF line ends
        assert_eq!(parse_ply(SQUARE.replace('\n', "\r\n").as_bytes()), Ok(ReferenceData::Mesh(square())));
    }

    #[test]
    fn written_triangles_read_back() {
        assert_eq!(parse_ply(&to_binary_ply(&square())), Ok(ReferenceData::Mesh(square())));
        // the vertices of a mesh, as points
        let (points, tris) = parse_parts(SQUARE.as_bytes()).expect("the square");
        assert_eq!(points.len(), 4);
        assert_eq!(points[3], [0.0, 1.0, 0.5]);
        assert_eq!(tris.map(|t| t.len()), Some(2));
    }

    #[test]
    fn a_file_without_faces_reads_as_points() {
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float32 x\nproperty float32 y\nproperty float32 z\nproperty float32 nx\nend_header\n1 2 3 0\n-4 5e1 6.5 1\n";
        assert_eq!(parse_ply(text.as_bytes()), Ok(ReferenceData::Points(vec![[1.0, 2.0, 3.0], [-4.0, 50.0, 6.5]])));
    }

    #[test]
    fn malformed_files_are_refused_with_the_record_or_line() {
        let err = |b: &[u8]| parse_ply(b).expect_err("accepted a malformed file").message;
        assert!(err(b"solid x\n").contains("not a PLY file"));
        assert!(err(SQUARE.replace("end_header\n", "").as_bytes()).contains("end_header"));
        assert!(err(SQUARE.replace("ascii", "binary").as_bytes()).contains("header line 2"));
        assert!(err(SQUARE.replace("float z", "quad z").as_bytes()).contains("header line 7"));
        assert!(err(SQUARE.replace("property float z\n", "").as_bytes()).contains("no `z`"));
        // a vertex that is not a number, named by record and line
        let e = err(SQUARE.replace("1 1 0 0", "1 oops 0 0").as_bytes());
        assert!(e.contains("vertex 2 (line 14)") && e.contains("oops"), "{e}");
        let e = err(SQUARE.replace("1 1 0 0", "1 nan 0 0").as_bytes());
        assert!(e.contains("vertex 2") && e.contains("NaN"), "{e}");
        // an index past the vertices, a face of two vertices
        assert!(err(SQUARE.replace("4 0 1 2 3", "4 0 1 2 9").as_bytes()).contains("face 0: vertex index 9"));
        assert!(err(SQUARE.replace("4 0 1 2 3", "2 0 1").as_bytes()).contains("a face of 2 vertices"));
        assert!(err(SQUARE.replace("4 0 1 2 3", "4 0 1 2 -1").as_bytes()).contains("not a whole number"));
        // truncated bodies
        let b = binary(false);
        assert!(err(&b[..b.len() - 3]).contains("the file ends"));
        let e = err(SQUARE.replace("4 0 1 2 3\n", "").as_bytes());
        assert!(e.contains("face 0") && e.contains("ends"), "{e}");
        // counts claimed beyond the file are refused before allocating
        let e = err(SQUARE.replace("element vertex 4", "element vertex 4000000000000").as_bytes());
        assert!(e.contains("claims 4000000000000 vertex records"), "{e}");
        let mut b = binary(false);
        let at = b.windows(4).position(|w| w == b"end_").unwrap_or(0) + "end_header\n".len() + 4 * 17 + 8;
        b[at] = 255;
        assert!(err(&b).contains("longer than the rest"), "list length");
        assert!(err(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n").contains("no vertices"));
    }
}
