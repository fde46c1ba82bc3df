//! ISO 10303-21 exchange structure ("STEP file"): a one-pass reader of the
//! text into entity records, written for the files exporters produce.
//!
//! It takes comments anywhere outside strings, `''` and the `\X\`, `\X2\`,
//! `\X4\` and `\S\` string escapes, empty aggregates, typed parameters
//! (`LENGTH_MEASURE(2.E-5)`), omitted (`$`) and derived (`*`) values, complex
//! instances (`#7 = (A() B(1) C(#2));`), several DATA sections and a missing
//! `END-ISO-10303-21;`. Every record keeps the line it starts on so that
//! errors and warnings can name it. Nesting depth and aggregate sizes are
//! bounded by the file's own length; a malformed record is an error naming its
//! line and entity, never a panic.

use std::collections::HashMap;

/// Deepest nesting of parenthesised aggregates accepted.
pub const MAX_NESTING: usize = 64;

/// One parameter of a record.
#[derive(Debug, Clone, PartialEq)]
pub enum Param {
    /// `#12`
    Ref(u64),
    /// An integer.
    Int(i64),
    /// A real (`1.`, `-2.5E-3`).
    Real(f64),
    /// A string, escapes decoded.
    Str(String),
    /// `.T.`, `.UNSPECIFIED.` (without the dots).
    Enum(String),
    /// `"0F1"` binary.
    Binary(String),
    /// `( … )`
    List(Vec<Param>),
    /// `LENGTH_MEASURE(2.0)`
    Typed(String, Box<Param>),
    /// `$`
    Omitted,
    /// `*`
    Derived,
}

impl Param {
    /// The number, for an integer or a real (also inside a typed parameter).
    pub fn number(&self) -> Option<f64> {
        match self {
            Param::Int(i) => Some(*i as f64),
            Param::Real(r) => Some(*r),
            Param::Typed(_, p) => p.number(),
            _ => None,
        }
    }
    /// The entity referred to.
    pub fn reference(&self) -> Option<u64> {
        match self {
            Param::Ref(r) => Some(*r),
            _ => None,
        }
    }
    /// The list's members.
    pub fn list(&self) -> Option<&[Param]> {
        match self {
            Param::List(l) => Some(l),
            _ => None,
        }
    }
    /// `.T.` → true, `.F.` → false.
    pub fn logical(&self) -> Option<bool> {
        match self {
            Param::Enum(e) if e == "T" => Some(true),
            Param::Enum(e) if e == "F" => Some(false),
            _ => None,
        }
    }
    /// The string's text.
    pub fn text(&self) -> Option<&str> {
        match self {
            Param::Str(s) => Some(s),
            _ => None,
        }
    }
}

/// One entity instance: a simple record (one part) or a complex one (its
/// parts in file order, each an entity name with the attributes it adds).
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Line of the file where the record starts (1-based).
    pub line: usize,
    /// `(ENTITY_NAME, parameters)`, upper case.
    pub parts: Vec<(String, Vec<Param>)>,
    /// Whether the record was written as a complex instance.
    pub complex: bool,
}

impl Record {
    /// The parameters of part `name`, if the record has it.
    pub fn part(&self, name: &str) -> Option<&[Param]> {
        self.parts.iter().find(|(n, _)| n == name).map(|(_, p)| p.as_slice())
    }
    /// Whether the record has part `name`.
    pub fn is(&self, name: &str) -> bool {
        self.parts.iter().any(|(n, _)| n == name)
    }
    /// The type's name for messages: the simple name, or the parts joined.
    pub fn type_name(&self) -> String {
        if self.complex {
            let names: Vec<&str> = self.parts.iter().map(|(n, _)| n.as_str()).collect();
            format!("({})", names.join(" "))
        } else {
            self.parts.first().map(|(n, _)| n.clone()).unwrap_or_default()
        }
    }
}

/// The file: header entities and the data section's instances.
#[derive(Debug, Clone, Default)]
pub struct Exchange {
    /// HEADER entities (`FILE_DESCRIPTION`, `FILE_NAME`, `FILE_SCHEMA`, …).
    pub header: Vec<(String, Vec<Param>)>,
    /// Instances by their `#` number.
    pub records: HashMap<u64, Record>,
    /// Duplicate instance numbers found (the later record replaces the earlier).
    pub duplicates: Vec<u64>,
}

impl Exchange {
    /// The schema names of `FILE_SCHEMA`.
    pub fn schemas(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (name, params) in &self.header {
            if name == "FILE_SCHEMA"
                && let Some(l) = params.first().and_then(Param::list)
            {
                out.extend(l.iter().filter_map(|p| p.text().map(str::to_string)));
            }
        }
        out
    }
}

/// A syntax error: the line and, once known, the instance it is in.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntaxError {
    /// 1-based line.
    pub line: usize,
    /// The instance being read, if any.
    pub entity: Option<u64>,
    /// What is wrong.
    pub message: String,
}

struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
    line: usize,
    entity: Option<u64>,
}

type Res<T> = Result<T, SyntaxError>;

impl<'a> Lexer<'a> {
    fn err<T>(&self, message: impl Into<String>) -> Res<T> {
        Err(SyntaxError { line: self.line, entity: self.entity, message: message.into() })
    }

    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    /// Skips white space and comments.
    fn skip(&mut self) -> Res<()> {
        loop {
            match self.peek() {
                Some(b'\n') => {
                    self.line += 1;
                    self.i += 1;
                }
                Some(c) if c.is_ascii_whitespace() => self.i += 1,
                Some(b'/') if self.s.get(self.i + 1) == Some(&b'*') => {
                    let start = self.line;
                    self.i += 2;
                    loop {
                        match self.peek() {
                            None => {
                                return Err(SyntaxError {
                                    line: start,
                                    entity: self.entity,
                                    message: "a comment that starts here never ends (no `*/`)".into(),
                                });
                            }
                            Some(b'*') if self.s.get(self.i + 1) == Some(&b'/') => {
                                self.i += 2;
                                break;
                            }
                            Some(b'\n') => {
                                self.line += 1;
                                self.i += 1;
                            }
                            Some(_) => self.i += 1,
                        }
                    }
                }
                _ => return Ok(()),
            }
        }
    }

    fn expect(&mut self, c: u8) -> Res<()> {
        self.skip()?;
        match self.peek() {
            Some(x) if x == c => {
                self.i += 1;
                Ok(())
            }
            Some(x) => self.err(format!("expected `{}`, found `{}`", c as char, show(x))),
            None => self.err(format!("the file ends where `{}` was expected", c as char)),
        }
    }

    /// A keyword: letters, digits, `_`, `-` (for `END-ISO-10303-21`), upper-cased.
    fn keyword(&mut self) -> Res<String> {
        self.skip()?;
        let start = self.i;
        while let Some(c) = self.peek() {
            if c.is_ascii_alphanumeric() || c == b'_' || c == b'-' || c == b'!' {
                self.i += 1;
            } else {
                break;
            }
        }
        if start == self.i {
            return match self.peek() {
                Some(c) => self.err(format!("expected a keyword, found `{}`", show(c))),
                None => self.err("the file ends where a keyword was expected"),
            };
        }
        Ok(String::from_utf8_lossy(&self.s[start..self.i]).to_ascii_uppercase())
    }

    fn integer(&mut self) -> Res<u64> {
        let start = self.i;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.i += 1;
        }
        let digits = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
        match digits.parse::<u64>() {
            Ok(v) => Ok(v),
            Err(_) if digits.is_empty() => self.err("`#` without an instance number"),
            Err(_) => self.err(format!("instance number {digits} is too large")),
        }
    }

    /// `( p, p, … )` after the opening parenthesis was seen.
    fn params(&mut self, depth: usize) -> Res<Vec<Param>> {
        if depth > MAX_NESTING {
            return self.err(format!("aggregates nest deeper than {MAX_NESTING} levels"));
        }
        self.expect(b'(')?;
        let mut out = Vec::new();
        self.skip()?;
        if self.peek() == Some(b')') {
            self.i += 1;
            return Ok(out);
        }
        loop {
            out.push(self.param(depth)?);
            self.skip()?;
            match self.peek() {
                Some(b',') => self.i += 1,
                Some(b')') => {
                    self.i += 1;
                    return Ok(out);
                }
                Some(c) => return self.err(format!("expected `,` or `)` after a parameter, found `{}`", show(c))),
                None => return self.err("the file ends inside a parameter list"),
            }
        }
    }

    fn param(&mut self, depth: usize) -> Res<Param> {
        self.skip()?;
        let Some(c) = self.peek() else {
            return self.err("the file ends where a parameter was expected");
        };
        match c {
            b'$' => {
                self.i += 1;
                Ok(Param::Omitted)
            }
            b'*' => {
                self.i += 1;
                Ok(Param::Derived)
            }
            b'#' => {
                self.i += 1;
                Ok(Param::Ref(self.integer()?))
            }
            b'\'' => Ok(Param::Str(self.string()?)),
            b'"' => {
                self.i += 1;
                let start = self.i;
                while self.peek().is_some_and(|c| c != b'"') {
                    self.i += 1;
                }
                if self.peek().is_none() {
                    return self.err("the file ends inside a binary value");
                }
                let v = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
                self.i += 1;
                Ok(Param::Binary(v))
            }
            b'.' if self.s.get(self.i + 1).is_some_and(|c| c.is_ascii_alphabetic() || *c == b'_') => {
                self.i += 1;
                let start = self.i;
                while self.peek().is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_') {
                    self.i += 1;
                }
                let v = String::from_utf8_lossy(&self.s[start..self.i]).to_ascii_uppercase();
                if self.peek() != Some(b'.') {
                    return self.err(format!("enumeration .{v} has no closing `.`"));
                }
                self.i += 1;
                Ok(Param::Enum(v))
            }
            b'(' => Ok(Param::List(self.params(depth + 1)?)),
            b'+' | b'-' | b'.' | b'0'..=b'9' => self.number(),
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let name = self.keyword()?;
                let mut inner = self.params(depth + 1)?;
                if inner.len() != 1 {
                    return self.err(format!("typed parameter {name}(…) holds {} values, not one", inner.len()));
                }
                Ok(Param::Typed(name, Box::new(inner.remove(0))))
            }
            c => self.err(format!("`{}` cannot start a parameter", show(c))),
        }
    }

    fn number(&mut self) -> Res<Param> {
        let start = self.i;
        if matches!(self.peek(), Some(b'+' | b'-')) {
            self.i += 1;
        }
        let mut real = false;
        while let Some(c) = self.peek() {
            match c {
                b'0'..=b'9' => self.i += 1,
                b'.' => {
                    real = true;
                    self.i += 1;
                }
                b'E' | b'e' => {
                    real = true;
                    self.i += 1;
                    if matches!(self.peek(), Some(b'+' | b'-')) {
                        self.i += 1;
                    }
                }
                _ => break,
            }
        }
        let t = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
        if real {
            // "1." and "1.E-3" are valid Part 21 reals; Rust parses both
            match t.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Param::Real(v)),
                _ => self.err(format!("`{t}` is not a number")),
            }
        } else {
            match t.parse::<i64>() {
                Ok(v) => Ok(Param::Int(v)),
                Err(_) => match t.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(Param::Real(v)),
                    _ => self.err(format!("`{t}` is not a number")),
                },
            }
        }
    }

    /// A quoted string with its escapes decoded.
    fn string(&mut self) -> Res<String> {
        let start_line = self.line;
        self.i += 1;
        let mut raw = Vec::new();
        loop {
            match self.peek() {
                None => {
                    return Err(SyntaxError {
                        line: start_line,
                        entity: self.entity,
                        message: "a string that starts here never ends".into(),
                    });
                }
                Some(b'\'') if self.s.get(self.i + 1) == Some(&b'\'') => {
                    raw.push(b'\'');
                    self.i += 2;
                }
                Some(b'\'') => {
                    self.i += 1;
                    break;
                }
                Some(c) => {
                    if c == b'\n' {
                        self.line += 1;
                    }
                    // line breaks inside strings are not part of the value
                    if c != b'\n' && c != b'\r' {
                        raw.push(c);
                    }
                    self.i += 1;
                }
            }
        }
        Ok(decode_string(&raw))
    }
}

fn show(c: u8) -> String {
    if c.is_ascii_graphic() { (c as char).to_string() } else { format!("\\x{c:02x}") }
}

/// Decodes `\X\hh` (ISO 8859-1), `\X2\hhhh…\X0\` (UCS-2), `\X4\hhhhhhhh…\X0\`
/// (UCS-4), `\S\c` (upper half of the page) and `\\`. Anything malformed is
/// kept as written.
pub fn decode_string(raw: &[u8]) -> String {
    let mut out = String::new();
    let mut i = 0;
    let hex = |s: &[u8]| std::str::from_utf8(s).ok().and_then(|t| u32::from_str_radix(t, 16).ok());
    while i < raw.len() {
        let rest = &raw[i..];
        if rest.starts_with(b"\\\\") {
            out.push('\\');
            i += 2;
        } else if rest.starts_with(b"\\X\\") && rest.len() >= 5 {
            match hex(&rest[3..5]).and_then(char::from_u32) {
                Some(c) => out.push(c),
                None => out.push_str(&String::from_utf8_lossy(&rest[..5])),
            }
            i += 5;
        } else if rest.starts_with(b"\\X2\\") || rest.starts_with(b"\\X4\\") {
            let width = if rest[2] == b'2' { 4 } else { 8 };
            let body = &rest[4..];
            let end = body.windows(4).position(|w| w == b"\\X0\\");
            match end {
                Some(e) if e % width == 0 => {
                    for chunk in body[..e].chunks(width) {
                        out.push(hex(chunk).and_then(char::from_u32).unwrap_or('\u{fffd}'));
                    }
                    i += 4 + e + 4;
                }
                _ => {
                    out.push_str(&String::from_utf8_lossy(rest));
                    i = raw.len();
                }
            }
        } else if rest.starts_with(b"\\S\\") && rest.len() >= 4 {
            out.push(char::from_u32(rest[3] as u32 + 128).unwrap_or('\u{fffd}'));
            i += 4;
        } else {
            // the text between escapes is ASCII by the standard; take UTF-8 leniently
            let next = rest.iter().skip(1).position(|&b| b == b'\\').map_or(rest.len(), |p| p + 1);
            out.push_str(&String::from_utf8_lossy(&rest[..next]));
            i += next;
        }
    }
    out
}

/// Reads the exchange structure from the file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Exchange, SyntaxError> {
    let mut lx = Lexer { s: bytes, i: 0, line: 1, entity: None };
    // skip a byte-order mark
    if bytes.starts_with(&[0xEF, 0xBB, 0xBF]) {
        lx.i = 3;
    }
    let magic = lx.keyword()?;
    if magic != "ISO-10303-21" {
        return lx.err(format!(
            "not a STEP file: it starts with `{}`, where ISO 10303-21 files start with `ISO-10303-21;`",
            magic.chars().take(40).collect::<String>()
        ));
    }
    lx.expect(b';')?;
    let mut ex = Exchange::default();
    let mut saw_data = false;
    loop {
        lx.skip()?;
        if lx.peek().is_none() {
            if saw_data {
                // a missing END-ISO-10303-21 loses nothing
                return Ok(ex);
            }
            return lx.err("the file ends before its DATA section");
        }
        let section = lx.keyword()?;
        match section.as_str() {
            "HEADER" => {
                lx.expect(b';')?;
                loop {
                    let k = lx.keyword()?;
                    if k == "ENDSEC" {
                        lx.expect(b';')?;
                        break;
                    }
                    let p = lx.params(0)?;
                    lx.expect(b';')?;
                    ex.header.push((k, p));
                }
            }
            "DATA" => {
                saw_data = true;
                lx.skip()?;
                // DATA may name a section: DATA('name', (schema));
                if lx.peek() == Some(b'(') {
                    lx.params(0)?;
                }
                lx.expect(b';')?;
                if let Err(mut e) = data_section(&mut lx, &mut ex) {
                    if lx.i >= lx.s.len() && !e.message.contains("truncated") {
                        e.message.push_str(": the file may be truncated");
                    }
                    return Err(e);
                }
            }
            "END-ISO-10303-21" => return Ok(ex),
            "ANCHOR" | "REFERENCE" | "SIGNATURE" => {
                // AP242 extensions: skip to ENDSEC
                loop {
                    lx.skip()?;
                    if lx.peek().is_none() {
                        return lx.err(format!("the {section} section never ends"));
                    }
                    if lx.peek() == Some(b'\'') {
                        lx.string()?;
                        continue;
                    }
                    if lx.s[lx.i..].starts_with(b"ENDSEC") {
                        lx.keyword()?;
                        lx.expect(b';')?;
                        break;
                    }
                    lx.i += 1;
                }
            }
            other => return lx.err(format!("unknown section `{other}` (expected HEADER, DATA or END-ISO-10303-21)")),
        }
    }
}

fn data_section(lx: &mut Lexer, ex: &mut Exchange) -> Res<()> {
    loop {
        lx.skip()?;
        lx.entity = None;
        match lx.peek() {
            Some(b'#') => {}
            Some(_) => {
                let k = lx.keyword()?;
                if k == "ENDSEC" {
                    return lx.expect(b';');
                }
                return lx.err(format!("expected an instance `#n = …;` or ENDSEC, found `{k}`"));
            }
            None => return lx.err("the file ends inside the DATA section (no ENDSEC): it may be truncated"),
        }
        let line = lx.line;
        lx.i += 1;
        let id = lx.integer()?;
        lx.entity = Some(id);
        lx.expect(b'=')?;
        lx.skip()?;
        let (parts, complex) = if lx.peek() == Some(b'(') {
            lx.i += 1;
            let mut parts = Vec::new();
            loop {
                lx.skip()?;
                match lx.peek() {
                    Some(b')') => {
                        lx.i += 1;
                        break;
                    }
                    None => return lx.err("the file ends inside a complex instance"),
                    _ => {
                        let name = lx.keyword()?;
                        let p = lx.params(0)?;
                        parts.push((name, p));
                    }
                }
            }
            if parts.is_empty() {
                return lx.err("a complex instance without parts");
            }
            (parts, true)
        } else {
            let name = lx.keyword()?;
            let p = lx.params(0)?;
            (vec![(name, p)], false)
        };
        lx.expect(b';')?;
        if ex.records.insert(id, Record { line, parts, complex }).is_some() {
            ex.duplicates.push(id);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "ISO-10303-21;\nHEADER;\n/* a comment */ FILE_DESCRIPTION(('x'),'2;1');\n\
        FILE_SCHEMA(('AUTOMOTIVE_DESIGN'));\nENDSEC;\nDATA;\n\
        #1 = CARTESIAN_POINT('it''s',(1.,-2.5E-1,3));\n\
        #2=( BOUNDED_CURVE() B_SPLINE_CURVE(1,(#1,#1),.UNSPECIFIED.,.F.,.F.) \n CURVE() );\n\
        #3 = UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(2.E-005),#1,'d\\X2\\00E9\\X0\\',$, *, ());\n\
        ENDSEC;\nEND-ISO-10303-21;\n";

    #[test]
    fn a_small_file_reads_with_every_kind_of_parameter() {
        let ex = parse(SMALL.as_bytes()).unwrap();
        assert_eq!(ex.schemas(), vec!["AUTOMOTIVE_DESIGN".to_string()]);
        let p = &ex.records[&1];
        assert_eq!(p.line, 7);
        assert_eq!(p.part("CARTESIAN_POINT").unwrap()[0], Param::Str("it's".into()));
        let xyz: Vec<f64> = p.parts[0].1[1].list().unwrap().iter().map(|v| v.number().unwrap()).collect();
        assert_eq!(xyz, vec![1.0, -0.25, 3.0]);
        let c = &ex.records[&2];
        assert!(c.complex && c.is("B_SPLINE_CURVE") && c.is("CURVE"));
        assert_eq!(c.part("B_SPLINE_CURVE").unwrap()[2], Param::Enum("UNSPECIFIED".into()));
        let u = &ex.records[&3].parts[0].1;
        assert_eq!(u[0].number(), Some(2e-5));
        assert_eq!(u[2], Param::Str("dé".into()));
        assert_eq!((&u[3], &u[4], &u[5]), (&Param::Omitted, &Param::Derived, &Param::List(vec![])));
    }

    #[test]
    fn broken_records_name_their_line_and_entity() {
        let cases: [(&str, usize, Option<u64>, &str); 6] = [
            ("#1 = POINT((1.,2.);\n", 7, Some(1), "expected `,` or `)`"),
            ("#1 = POINT('abc);\nENDSEC;\n", 7, Some(1), "never ends"),
            ("#1 = POINT(@);\n", 7, Some(1), "cannot start"),
            ("#1 = POINT(1.);\n#2 = POINT(2.)\n#3 = X();\n", 9, Some(2), "expected `;`"),
            ("#1 = POINT(1.);\n", 8, None, "truncated"),
            ("#1 = POINT(1.E999);\n", 7, Some(1), "not a number"),
        ];
        for (body, line, entity, text) in cases {
            let file = format!("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nENDSEC;\n\n\nDATA;\n{body}");
            let file = file.replacen("DATA;\n", "DATA;", 1);
            let e = parse(file.as_bytes()).unwrap_err();
            assert_eq!((e.line, e.entity), (line, entity), "{body}: {e:?}");
            assert!(e.message.contains(text), "{body}: {}", e.message);
        }
        let e = parse(b"solid cube\nfacet normal 0 0 1\n").unwrap_err();
        assert!(e.message.contains("not a STEP file"), "{}", e.message);
        let deep = format!("ISO-10303-21;\nDATA;\n#1 = X({}{});\nENDSEC;\n", "(".repeat(200), ")".repeat(200));
        assert!(parse(deep.as_bytes()).unwrap_err().message.contains("nest deeper"));
    }

    #[test]
    fn string_escapes_decode() {
        assert_eq!(decode_string(b"a\\X\\E9b"), "a\u{e9}b");
        assert_eq!(decode_string(b"\\X2\\03B103B2\\X0\\!"), "\u{3b1}\u{3b2}!");
        assert_eq!(decode_string(b"\\X4\\0001F600\\X0\\"), "\u{1f600}");
        assert_eq!(decode_string(b"\\S\\a"), "\u{e1}");
        assert_eq!(decode_string(b"back\\\\slash"), "back\\slash");
        // malformed escapes stay as written
        assert_eq!(decode_string(b"\\X2\\00E"), "\\X2\\00E");
    }
}
