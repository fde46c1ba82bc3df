//! The Global section: its delimiters, parameters and length unit, and
//! IGES numbers.

pub(super) fn delimiters(global: &str, repairs: &mut Vec<String>) -> (char, char) {
    let g = global.trim_start();
    let hollerith = |s: &str| -> Option<(char, usize)> {
        let rest = s.strip_prefix("1H")?;
        let c = rest.chars().next()?;
        Some((c, 2 + c.len_utf8()))
    };
    let (pd, used) = hollerith(g).unwrap_or((',', 0));
    let after = &g[used..];
    let after = after.strip_prefix(pd).unwrap_or(after);
    let rd = match hollerith(after) {
        Some((c, _)) => c,
        None => {
            if after.trim().is_empty() {
                repairs.push("global section ends after the parameter delimiter: record delimiter ';' assumed".into());
            }
            ';'
        }
    };
    (pd, rd)
}

/// The global section's parameters in order (Hollerith strings as their
/// text), up to the record delimiter.
pub(super) fn global_params(global: &str, pd: char, rd: char) -> Vec<String> {
    let chars: Vec<char> = global.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i <= chars.len() {
        // skip blanks before a parameter
        while i < chars.len() && chars[i] == ' ' {
            i += 1;
        }
        let digits = chars[i..].iter().take_while(|c| c.is_ascii_digit()).count();
        let value = if digits > 0 && chars.get(i + digits).is_some_and(|c| *c == 'H' || *c == 'h') {
            // nHtext: n characters taken as they are, delimiters included
            let n: usize = chars[i..i + digits].iter().collect::<String>().parse().unwrap_or(0);
            let start = i + digits + 1;
            let end = (start + n).min(chars.len());
            i = end;
            chars[start..end].iter().collect::<String>()
        } else {
            let start = i;
            while i < chars.len() && chars[i] != pd && chars[i] != rd {
                i += 1;
            }
            chars[start..i].iter().collect::<String>().trim().to_string()
        };
        out.push(value);
        while i < chars.len() && chars[i] == ' ' {
            i += 1;
        }
        match chars.get(i) {
            Some(c) if *c == pd => i += 1,
            _ => break,
        }
    }
    out
}

/// [`global_params`] with the default delimiters, for tests elsewhere in the crate.
#[cfg(test)]
pub(crate) fn tests_global_params(global: &str) -> Vec<String> {
    global_params(global, ',', ';')
}

/// The length unit of the global parameters 14 (unit flag) and 15 (unit
/// name), as the other readers name units ("mm", "inch", …).
pub(super) fn global_units(params: &[String]) -> Option<String> {
    let flag = params.get(13).and_then(|f| f.trim().parse::<i64>().ok());
    let name = params.get(14).map(|n| n.trim().to_ascii_uppercase()).unwrap_or_default();
    let by_flag = match flag {
        Some(1) => Some("inch"),
        Some(2) => Some("mm"),
        Some(4) => Some("ft"),
        Some(5) => Some("mile"),
        Some(6) => Some("m"),
        Some(7) => Some("km"),
        Some(8) => Some("mil"),
        Some(9) => Some("µm"),
        Some(10) => Some("cm"),
        Some(11) => Some("microinch"),
        _ => None,
    };
    by_flag.map(str::to_string).or_else(|| {
        // flag 3: the unit is the name (e.g. 4HINCH, 2HMM)
        let from_name = match name.as_str() {
            "IN" | "INCH" => "inch",
            "MM" => "mm",
            "FT" => "ft",
            "MI" => "mile",
            "M" => "m",
            "KM" => "km",
            "MIL" => "mil",
            "UM" => "µm",
            "CM" => "cm",
            "UIN" => "microinch",
            _ => return (!name.is_empty()).then(|| name.to_ascii_lowercase()),
        };
        Some(from_name.to_string())
    })
}

/// The IGES unit flag and name of a length unit named as `global_units`
/// names them; `None` for a unit IGES has no flag for.
pub fn iges_unit(units: &str) -> Option<(u32, &'static str)> {
    Some(match units {
        "inch" => (1, "INCH"),
        "mm" => (2, "MM"),
        "ft" => (4, "FT"),
        "mile" => (5, "MI"),
        "m" => (6, "M"),
        "km" => (7, "KM"),
        "mil" => (8, "MIL"),
        "µm" => (9, "UM"),
        "cm" => (10, "CM"),
        "microinch" => (11, "UIN"),
        _ => return None,
    })
}

pub(super) fn num(s: &str) -> Option<f64> {
    let t = s.trim().replace(['D', 'd'], "E");
    t.parse::<f64>().ok().filter(|v| v.is_finite())
}
