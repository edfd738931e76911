//! Reading one query file of the CCD benchmark: 8 rows per query, each row
//! `x_num,x_den,y_num,y_den,z_num,z_den,truth` with integer numerators of at most 53 bits and
//! power-of-two denominators (which may exceed 2^63), so that every coordinate is an exact f64.
//! Anything else is refused with the line it is on, rather than rounded.

use palpa::Vec3;
use std::collections::HashMap;

/// Which primitives the 8 points of a query are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Rows: v_t0, f0_t0, f1_t0, f2_t0, v_t1, f0_t1, f1_t1, f2_t1.
    VertexFace,
    /// Rows: ea0_t0, ea1_t0, eb0_t0, eb1_t0, ea0_t1, ea1_t1, eb0_t1, eb1_t1.
    EdgeEdge,
}

impl Kind {
    /// The folder name and JSON value of the kind.
    pub fn name(self) -> &'static str {
        match self {
            Kind::VertexFace => "vertex-face",
            Kind::EdgeEdge => "edge-edge",
        }
    }
}

/// One query: its 8 positions in file order and the ground truth.
#[derive(Clone, Debug, PartialEq)]
pub struct Query {
    /// Positions in the order of the file's rows.
    pub points: [Vec3; 8],
    /// True when the primitives touch at some t in [0, 1] (exact ground truth).
    pub truth: bool,
}

/// Parses a whole file. Errors read `line N: what is wrong` (1-based line numbers).
/// Blank lines are skipped.
pub fn parse_query_file(text: &str) -> Result<Vec<Query>, String> {
    let mut parser = Parser::default();
    let mut queries = Vec::new();
    let mut points = [Vec3::zeros(); 8];
    let mut truth = false;
    let mut rows = 0usize;
    let mut last_line = 0usize;
    for (index, line) in text.lines().enumerate() {
        let number = index + 1;
        if line.trim().is_empty() {
            continue;
        }
        last_line = number;
        let (point, row_truth) = parser
            .parse_row(line)
            .map_err(|e| format!("line {number}: {e}"))?;
        let slot = rows % 8;
        if slot == 0 {
            truth = row_truth;
        } else if row_truth != truth {
            return Err(format!(
                "line {number}: truth {} differs from the {} on the first row of this query (line {})",
                u8::from(row_truth),
                u8::from(truth),
                number - slot
            ));
        }
        points[slot] = point;
        rows += 1;
        if slot == 7 {
            queries.push(Query { points, truth });
        }
    }
    if rows % 8 != 0 {
        return Err(format!(
            "line {last_line}: the file ends inside a query ({rows} rows, not a multiple of 8)"
        ));
    }
    Ok(queries)
}

/// Remembers the decimal digits of the large powers of two met so far.
#[derive(Default)]
struct Parser {
    powers_of_two: HashMap<u32, String>,
}

impl Parser {
    fn parse_row(&mut self, line: &str) -> Result<(Vec3, bool), String> {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(format!(
                "expected 7 comma-separated columns (x_num,x_den,y_num,y_den,z_num,z_den,truth), found {}",
                fields.len()
            ));
        }
        let mut point = Vec3::zeros();
        for (axis, name) in ["x", "y", "z"].into_iter().enumerate() {
            let numerator = parse_numerator(fields[2 * axis])
                .map_err(|e| format!("{name} numerator {:?}: {e}", fields[2 * axis]))?;
            let exponent = self
                .parse_denominator(fields[2 * axis + 1])
                .map_err(|e| format!("{name} denominator {:?}: {e}", fields[2 * axis + 1]))?;
            point[axis] = exact_quotient(numerator, exponent).ok_or_else(|| {
                format!(
                    "{name} = {}/2^{exponent} is not exactly representable as f64",
                    fields[2 * axis]
                )
            })?;
        }
        let truth = match fields[6] {
            "0" => false,
            "1" => true,
            other => return Err(format!("truth {other:?}: expected 0 or 1")),
        };
        Ok((point, truth))
    }

    /// The exponent e of a denominator 2^e, checked digit for digit.
    fn parse_denominator(&mut self, field: &str) -> Result<u32, String> {
        if field.is_empty() || !field.bytes().all(|b| b.is_ascii_digit()) {
            return Err("not a positive integer".to_string());
        }
        let digits = field.trim_start_matches('0');
        if digits.len() <= 19 {
            // Fits in u64.
            let value: u64 = digits.parse().map_err(|_| "not a positive integer")?;
            return if value.is_power_of_two() {
                Ok(value.trailing_zeros())
            } else {
                Err("not a power of two".to_string())
            };
        }
        // Large: the nearest f64 tells which power it would be, the digits must then match exactly.
        let approximate: f64 = digits.parse().map_err(|_| "not a positive integer")?;
        let bits = approximate.to_bits();
        let is_power = approximate.is_finite() && bits & ((1u64 << 52) - 1) == 0;
        if !is_power {
            return Err("not a power of two (or too large)".to_string());
        }
        let exponent = ((bits >> 52) as u32) - 1023;
        let exact = self
            .powers_of_two
            .entry(exponent)
            .or_insert_with(|| decimal_power_of_two(exponent));
        if exact == digits {
            Ok(exponent)
        } else {
            Err("not a power of two".to_string())
        }
    }
}

/// A signed integer of at most 53 bits (so exact as f64).
fn parse_numerator(field: &str) -> Result<i64, String> {
    let value: i64 = field
        .parse()
        .map_err(|_| "not an integer of at most 53 bits".to_string())?;
    if value.unsigned_abs() > 1u64 << 53 {
        return Err("more than 53 bits".to_string());
    }
    Ok(value)
}

/// numerator / 2^exponent when it is an exact f64 (it is not only when it would fall below the
/// smallest subnormal's precision).
fn exact_quotient(numerator: i64, exponent: u32) -> Option<f64> {
    if numerator == 0 {
        return Some(0.0);
    }
    // numerator = odd × 2^shift, so the value is odd × 2^power. With odd below 2^53 that is a
    // double exactly when its lowest bit, 2^power, is not below the smallest subnormal 2^−1074 and
    // its highest bit is not above 2^1023.
    let shift = numerator.trailing_zeros();
    let odd = numerator >> shift;
    let power = i64::from(shift) - i64::from(exponent);
    let bits_of_odd = i64::from(64 - odd.unsigned_abs().leading_zeros());
    if power < -1074 || power + bits_of_odd - 1 > 1023 {
        return None;
    }
    Some(odd as f64 * power_of_two(power))
}

/// 2^p exactly, for −1074 ≤ p ≤ 1023 (subnormal below −1022).
fn power_of_two(p: i64) -> f64 {
    if p >= -1022 {
        f64::from_bits(((p + 1023) as u64) << 52)
    } else {
        f64::from_bits(1u64 << (p + 1074))
    }
}

/// The decimal digits of 2^e, by repeated doubling (only for the few large denominators of a file).
fn decimal_power_of_two(e: u32) -> String {
    // Little-endian decimal digits.
    let mut digits = vec![1u8];
    for _ in 0..e {
        let mut carry = 0u8;
        for d in digits.iter_mut() {
            let x = *d * 2 + carry;
            *d = x % 10;
            carry = x / 10;
        }
        if carry > 0 {
            digits.push(carry);
        }
    }
    digits.iter().rev().map(|d| char::from(b'0' + d)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_values_and_big_denominators() {
        let mut p = Parser::default();
        let (x, truth) = p.parse_row("3,4,-1,1180591620717411303424,0,1,1").unwrap();
        assert!(truth);
        assert_eq!(x, Vec3::new(0.75, -(2f64.powi(-70)), 0.0));
        assert_eq!(
            p.parse_denominator("1180591620717411303425"),
            Err("not a power of two".into())
        );
        assert!(p.parse_denominator("6").is_err());
        assert!(p.parse_denominator("-2").is_err());
        assert_eq!(exact_quotient(3, 1075), None);
        assert_eq!(exact_quotient(1, 1074), Some(f64::from_bits(1)));
    }

    #[test]
    fn errors_name_the_line() {
        let good = "0,1,0,1,0,1,0\n".repeat(8);
        assert_eq!(parse_query_file(&good).map(|q| q.len()), Ok(1));
        let short = good.replacen("0,1,0,1,0,1,0\n", "0,1,0,1,0,1\n", 1);
        assert!(
            parse_query_file(&short)
                .unwrap_err()
                .starts_with("line 1: expected 7")
        );
        let truncated = "0,1,0,1,0,1,0\n".repeat(9);
        assert!(
            parse_query_file(&truncated)
                .unwrap_err()
                .starts_with("line 9: the file ends")
        );
        let mixed = format!("{}0,1,0,1,0,1,1\n", "0,1,0,1,0,1,0\n".repeat(7));
        assert!(
            parse_query_file(&mixed)
                .unwrap_err()
                .starts_with("line 8: truth 1 differs")
        );
        let word = good.replacen("0,1,0,1,0,1,0", "0,1,zero,1,0,1,0", 1);
        assert!(
            parse_query_file(&word)
                .unwrap_err()
                .contains("y numerator \"zero\"")
        );
    }
}
