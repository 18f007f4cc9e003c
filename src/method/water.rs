//! Water types: the search space of the two attenuation ratios (METHOD §1).

use crate::error::{Error, Result};

/// One candidate water: beta_BR = beta_B / beta_R and beta_BG = beta_B / beta_G.
#[derive(Debug, Clone, PartialEq)]
pub struct WaterType {
    /// Display name ("I", "IA", ..., "9C", or a user's own).
    pub name: String,
    /// beta_B / beta_R.
    pub beta_br: f64,
    /// beta_B / beta_G.
    pub beta_bg: f64,
}

/// Largest ratio accepted for a custom type (the Jerlov table stays below
/// 2.1). Beyond it the powers in METHOD §4 and 7 lose all meaning for data in
/// [0, 1], and METHOD §7's floor of t_B, 0.1^beta_BR, is no longer a normal f32
/// (at 45 it underflows to 0 and t_B = 0 reaches the output; found by the
/// property tests).
pub const MAX_RATIO: f64 = 30.0;

/// Smallest ratio accepted, 1 / `MAX_RATIO` (the Jerlov table stays above
/// 0.11): the exponents 1 / beta_BR of METHOD §4 and 7 stay within those of
/// the largest ratio (a subnormal ratio made them infinite and every pixel
/// NaN).
pub const MIN_RATIO: f64 = 1.0 / MAX_RATIO;

/// The Jerlov (1968) table of METHOD §1: (name, beta_BR, beta_BG).
pub const JERLOV: [(&str, f64, f64); 10] = [
    ("I", 0.1118, 0.4566),
    ("IA", 0.1452, 0.5499),
    ("IB", 0.1745, 0.6341),
    ("II", 0.2773, 0.7937),
    ("III", 0.4051, 0.9539),
    ("1C", 0.4642, 1.0930),
    ("3C", 0.6515, 1.1244),
    ("5C", 1.0000, 1.2725),
    ("7C", 1.4500, 1.4022),
    ("9C", 2.0708, 1.5942),
];

/// Most candidate types of one restoration: each keeps some 40 KB of the
/// type choice's state that the memory plan does not count (10,000 types
/// on a 64 x 64 image took 373 MB), and a dense grid of 30 x 30 ratios
/// stays within it.
pub const MAX_TYPES: usize = 1000;

/// The longest name of a water type (characters).
pub const MAX_NAME: usize = 64;

impl WaterType {
    /// A custom water type; both ratios must be finite and in [`MIN_RATIO`, `MAX_RATIO`].
    pub fn new(name: &str, beta_br: f64, beta_bg: f64) -> Result<Self> {
        for (label, v) in [("beta_BR", beta_br), ("beta_BG", beta_bg)] {
            if !v.is_finite() || !(MIN_RATIO..=MAX_RATIO).contains(&v) {
                return Err(Error::WaterType(format!(
                    "{label} of water type {name:?} is {}; it must be a finite number in [1/{MAX_RATIO}, {MAX_RATIO}]",
                    crate::error::shown_number(v)
                )));
            }
        }
        if name.is_empty() {
            return Err(Error::WaterType(
                "a water type needs a non-empty name".into(),
            ));
        }
        // the name is printed on consoles, written into CSV cells and pages:
        // a label, not a carrier of escape sequences or line breaks
        if name.chars().any(char::is_control) || name.chars().count() > MAX_NAME {
            return Err(Error::WaterType(format!(
                "a water type's name is at most {MAX_NAME} characters without control characters, not {:?}",
                name.chars().take(MAX_NAME).collect::<String>()
            )));
        }
        Ok(Self {
            name: name.to_string(),
            beta_br,
            beta_bg,
        })
    }

    /// A type of the Jerlov table by its name in any ASCII case (`3c` is
    /// `3C`), named as the table names it (METHOD §1).
    pub fn by_name(name: &str) -> Result<Self> {
        table_entry(name)
            .map(|&(n, br, bg)| Self {
                name: n.to_string(),
                beta_br: br,
                beta_bg: bg,
            })
            .ok_or_else(|| {
                let names: Vec<&str> = JERLOV.iter().map(|t| t.0).collect();
                Error::WaterType(format!(
                    "unknown water type {name:?}; known types: {}",
                    names.join(", ")
                ))
            })
    }
}

/// The row of the Jerlov table named `name` in any ASCII case (METHOD §1).
pub fn table_entry(name: &str) -> Option<&'static (&'static str, f64, f64)> {
    JERLOV.iter().find(|(n, _, _)| n.eq_ignore_ascii_case(name))
}

/// All ten Jerlov types in table order (the default search space).
pub fn jerlov_types() -> Vec<WaterType> {
    JERLOV
        .iter()
        .map(|&(n, br, bg)| WaterType {
            name: n.to_string(),
            beta_br: br,
            beta_bg: bg,
        })
        .collect()
}

/// Checks a list of candidate types: non-empty, names unique.
pub fn validate_types(types: &[WaterType]) -> Result<()> {
    if types.is_empty() {
        return Err(Error::WaterType("the list of water types is empty".into()));
    }
    if types.len() > MAX_TYPES {
        return Err(Error::WaterType(format!(
            "{} water types are listed; at most {MAX_TYPES} are searched",
            types.len()
        )));
    }
    for (i, t) in types.iter().enumerate() {
        WaterType::new(&t.name, t.beta_br, t.beta_bg)?;
        // names are told apart in any case, as table names are read (a custom
        // "ia" beside the table's IA would be two types of one name)
        if types.iter().take(i).any(|o| o.name.eq_ignore_ascii_case(&t.name)) {
            return Err(Error::WaterType(format!(
                "water type {:?} is listed twice",
                t.name
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_ten_types_in_order() {
        let t = jerlov_types();
        assert_eq!(t.len(), 10);
        assert_eq!(t[0].name, "I");
        assert_eq!(t[9].name, "9C");
        // 5C is where red and blue attenuate alike (METHOD §1).
        assert_eq!(WaterType::by_name("5C").unwrap().beta_br, 1.0);
        assert_eq!(WaterType::by_name("ib").unwrap().name, "IB");
        // two types whose names differ only in case are one name listed twice
        let custom = |n: &str, br: f64, bg: f64| WaterType { name: n.into(), beta_br: br, beta_bg: bg };
        let ia = WaterType::by_name("IA").unwrap();
        assert!(validate_types(&[ia.clone(), custom("ia", 0.5, 0.6)]).unwrap_err().to_string().contains("listed twice"));
        // a fitted water named by its nearest type (--water-from) is a type of its own
        assert!(validate_types(&[custom("IA", 0.5, 0.6)]).is_ok());
        assert!(validate_types(&[ia, custom("mine", 0.5, 0.6)]).is_ok());
    }

    #[test]
    fn unknown_and_bad_types_are_errors() {
        let e = WaterType::by_name("XI").unwrap_err().to_string();
        assert!(e.contains("XI") && e.contains("known types"), "{e}");
        assert!(WaterType::new("x", 0.0, 1.0).is_err());
        assert!(WaterType::new("x", -1.0, 1.0).is_err());
        assert!(WaterType::new("x", f64::NAN, 1.0).is_err());
        assert!(WaterType::new("x", 1.0, f64::INFINITY).is_err());
        assert!(WaterType::new("", 1.0, 1.0).is_err());
        // a label: no escape sequences or line breaks, at most MAX_NAME characters
        assert!(WaterType::new("a\u{1b}[31m", 1.0, 1.0).is_err());
        assert!(WaterType::new("a\nb", 1.0, 1.0).is_err());
        assert!(WaterType::new(&"é".repeat(MAX_NAME), 1.0, 1.0).is_ok());
        assert!(WaterType::new(&"é".repeat(MAX_NAME + 1), 1.0, 1.0).is_err());
        assert!(WaterType::new("x", MAX_RATIO, 1.0).is_ok());
        assert!(WaterType::new("x", MAX_RATIO * 1.01, 1.0).is_err());
        assert!(WaterType::new("x", 1.0, 1.0 / 30.0).is_ok());
        // a subnormal ratio made 1 / beta_BR infinite and every pixel NaN
        assert!(WaterType::new("x", 1e-310, 1.0).is_err());
        assert!(WaterType::new("x", 1.0, 0.99 / 30.0).is_err());
        // the t_B floor of METHOD §7 stays a normal f32 for every accepted ratio
        assert!(0.1f32.powf(MAX_RATIO as f32) >= f32::MIN_POSITIVE);
        assert!(validate_types(&[]).is_err());
        let grid: Vec<WaterType> = (0..=MAX_TYPES).map(|k| WaterType::new(&format!("g{k}"), 1.0, 1.0).unwrap()).collect();
        assert!(validate_types(&grid[..MAX_TYPES]).is_ok());
        assert!(validate_types(&grid).is_err());
        let a = WaterType::new("a", 1.0, 1.0).unwrap();
        assert!(validate_types(&[a.clone(), a]).is_err());
    }
}
