//! Reading one query file of the CCD benchmark: 8 rows per query, each row
//! `x_num,x_den,y_num,y_den,z_num,z_den,truth` with integer numerators of at most 53 bits and
//! power-of-two denominators (which may exceed 2^63), so that every coordinate is an exact f64.
//! Anything else is refused with the line it is on, rather than rounded.

use palpa::Vec3;
use std::collections::HashMap;
use std::fmt;

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

/// What is wrong with a query file, and on which line (1-based). Every message reads
/// `line N: what is wrong`; it is the whole message (the reason included), so no variant has a
/// `#[source]` that a printer of the error chain would repeat.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum QueryFileError {
    /// A row without exactly 7 comma-separated fields.
    #[error(
        "line {line}: expected 7 comma-separated columns (x_num,x_den,y_num,y_den,z_num,z_den,truth), found {found}"
    )]
    ColumnCount { line: usize, found: usize },
    /// A numerator that is not an integer of at most 53 bits.
    #[error("line {line}: {axis} numerator {text:?}: {reason}")]
    Numerator {
        line: usize,
        axis: Axis,
        text: String,
        reason: NumeratorError,
    },
    /// A denominator that is not a power of two (or not a number at all).
    #[error("line {line}: {axis} denominator {text:?}: {reason}")]
    Denominator {
        line: usize,
        axis: Axis,
        text: String,
        reason: DenominatorError,
    },
    /// A coordinate `numerator/2^exponent` that no f64 holds exactly.
    #[error("line {line}: {axis} = {numerator}/2^{exponent} is not exactly representable as f64")]
    Inexact {
        line: usize,
        axis: Axis,
        numerator: String,
        exponent: u32,
    },
    /// A truth field other than `0` or `1`.
    #[error("line {line}: truth {text:?}: expected 0 or 1")]
    Truth { line: usize, text: String },
    /// A row whose truth is not that of its query's first row.
    #[error(
        "line {line}: truth {} differs from the {} on the first row of this query (line {first_line})",
        u8::from(*truth),
        u8::from(*first_truth)
    )]
    TruthDiffers {
        line: usize,
        truth: bool,
        first_line: usize,
        first_truth: bool,
    },
    /// A file whose row count is not a multiple of 8; `line` is its last non-blank line.
    #[error("line {line}: the file ends inside a query ({rows} rows, not a multiple of 8)")]
    EndsInsideQuery { line: usize, rows: usize },
}

/// Why a numerator field was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NumeratorError {
    #[error("not an integer of at most 53 bits")]
    NotAnInteger,
    #[error("more than 53 bits")]
    TooManyBits,
}

/// Why a denominator field was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DenominatorError {
    #[error("not a positive integer")]
    NotAnInteger,
    #[error("not a power of two")]
    NotPowerOfTwo,
    /// Over 19 digits and beyond the f64 range, or not even near a power of two.
    #[error("not a power of two (or too large)")]
    TooLarge,
}

/// The coordinate a field belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        })
    }
}

/// Parses a whole file. Errors read `line N: what is wrong` (1-based line numbers).
/// Blank lines are skipped.
pub fn parse_query_file(text: &str) -> Result<Vec<Query>, QueryFileError> {
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
        let (point, row_truth) = parser.parse_row(number, line)?;
        let slot = rows % 8;
        if slot == 0 {
            truth = row_truth;
        } else if row_truth != truth {
            return Err(QueryFileError::TruthDiffers {
                line: number,
                truth: row_truth,
                first_line: number - slot,
                first_truth: truth,
            });
        }
        points[slot] = point;
        rows += 1;
        if slot == 7 {
            queries.push(Query { points, truth });
        }
    }
    if rows % 8 != 0 {
        return Err(QueryFileError::EndsInsideQuery {
            line: last_line,
            rows,
        });
    }
    Ok(queries)
}

/// Remembers the decimal digits of the large powers of two met so far.
#[derive(Default)]
struct Parser {
    powers_of_two: HashMap<u32, String>,
}

impl Parser {
    /// The point and truth of the row on line `number`.
    fn parse_row(&mut self, number: usize, line: &str) -> Result<(Vec3, bool), QueryFileError> {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(QueryFileError::ColumnCount {
                line: number,
                found: fields.len(),
            });
        }
        let mut point = Vec3::zeros();
        for (index, axis) in [Axis::X, Axis::Y, Axis::Z].into_iter().enumerate() {
            let (numerator_text, denominator_text) = (fields[2 * index], fields[2 * index + 1]);
            let numerator =
                parse_numerator(numerator_text).map_err(|reason| QueryFileError::Numerator {
                    line: number,
                    axis,
                    text: numerator_text.to_string(),
                    reason,
                })?;
            let exponent = self.parse_denominator(denominator_text).map_err(|reason| {
                QueryFileError::Denominator {
                    line: number,
                    axis,
                    text: denominator_text.to_string(),
                    reason,
                }
            })?;
            point[index] =
                exact_quotient(numerator, exponent).ok_or_else(|| QueryFileError::Inexact {
                    line: number,
                    axis,
                    numerator: numerator_text.to_string(),
                    exponent,
                })?;
        }
        let truth = match fields[6] {
            "0" => false,
            "1" => true,
            other => {
                return Err(QueryFileError::Truth {
                    line: number,
                    text: other.to_string(),
                });
            }
        };
        Ok((point, truth))
    }

    /// The exponent e of a denominator 2^e, checked digit for digit.
    fn parse_denominator(&mut self, field: &str) -> Result<u32, DenominatorError> {
        if field.is_empty() || !field.bytes().all(|b| b.is_ascii_digit()) {
            return Err(DenominatorError::NotAnInteger);
        }
        let digits = field.trim_start_matches('0');
        if digits.len() <= 19 {
            // Fits in u64.
            let value: u64 = digits.parse().map_err(|_| DenominatorError::NotAnInteger)?;
            return if value.is_power_of_two() {
                Ok(value.trailing_zeros())
            } else {
                Err(DenominatorError::NotPowerOfTwo)
            };
        }
        // Large: the nearest f64 tells which power it would be, the digits must then match exactly.
        let approximate: f64 = digits.parse().map_err(|_| DenominatorError::NotAnInteger)?;
        let bits = approximate.to_bits();
        let is_power = approximate.is_finite() && bits & ((1u64 << 52) - 1) == 0;
        if !is_power {
            return Err(DenominatorError::TooLarge);
        }
        let exponent = ((bits >> 52) as u32) - 1023;
        let exact = self
            .powers_of_two
            .entry(exponent)
            .or_insert_with(|| decimal_power_of_two(exponent));
        if exact == digits {
            Ok(exponent)
        } else {
            Err(DenominatorError::NotPowerOfTwo)
        }
    }
}

/// A signed integer of at most 53 bits (so exact as f64).
fn parse_numerator(field: &str) -> Result<i64, NumeratorError> {
    let value: i64 = field.parse().map_err(|_| NumeratorError::NotAnInteger)?;
    if value.unsigned_abs() > 1u64 << 53 {
        return Err(NumeratorError::TooManyBits);
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
        let (x, truth) = p
            .parse_row(1, "3,4,-1,1180591620717411303424,0,1,1")
            .unwrap();
        assert!(truth);
        assert_eq!(x, Vec3::new(0.75, -(2f64.powi(-70)), 0.0));
        assert_eq!(
            p.parse_denominator("1180591620717411303425"),
            Err(DenominatorError::NotPowerOfTwo)
        );
        assert_eq!(
            p.parse_denominator("6"),
            Err(DenominatorError::NotPowerOfTwo)
        );
        assert_eq!(
            p.parse_denominator("-2"),
            Err(DenominatorError::NotAnInteger)
        );
        assert_eq!(
            parse_numerator("9007199254740993"),
            Err(NumeratorError::TooManyBits)
        );
        assert_eq!(exact_quotient(3, 1075), None);
        assert_eq!(exact_quotient(1, 1074), Some(f64::from_bits(1)));
    }

    #[test]
    fn errors_name_the_line() {
        let good = "0,1,0,1,0,1,0\n".repeat(8);
        assert_eq!(parse_query_file(&good).map(|q| q.len()), Ok(1));
        let short = good.replacen("0,1,0,1,0,1,0\n", "0,1,0,1,0,1\n", 1);
        let error = parse_query_file(&short).unwrap_err();
        assert_eq!(error, QueryFileError::ColumnCount { line: 1, found: 6 });
        assert!(error.to_string().starts_with("line 1: expected 7"));
        let truncated = "0,1,0,1,0,1,0\n".repeat(9);
        let error = parse_query_file(&truncated).unwrap_err();
        assert_eq!(error, QueryFileError::EndsInsideQuery { line: 9, rows: 9 });
        assert!(error.to_string().starts_with("line 9: the file ends"));
        let mixed = format!("{}0,1,0,1,0,1,1\n", "0,1,0,1,0,1,0\n".repeat(7));
        let error = parse_query_file(&mixed).unwrap_err();
        assert_eq!(
            error,
            QueryFileError::TruthDiffers {
                line: 8,
                truth: true,
                first_line: 1,
                first_truth: false
            }
        );
        assert_eq!(
            error.to_string(),
            "line 8: truth 1 differs from the 0 on the first row of this query (line 1)"
        );
        let word = good.replacen("0,1,0,1,0,1,0", "0,1,zero,1,0,1,0", 1);
        let error = parse_query_file(&word).unwrap_err();
        assert_eq!(
            error,
            QueryFileError::Numerator {
                line: 1,
                axis: Axis::Y,
                text: "zero".into(),
                reason: NumeratorError::NotAnInteger
            }
        );
        assert_eq!(
            error.to_string(),
            "line 1: y numerator \"zero\": not an integer of at most 53 bits"
        );
        let truth = good.replacen("0,1,0,1,0,1,0", "0,1,0,1,0,1,2", 1);
        assert_eq!(
            parse_query_file(&truth).unwrap_err().to_string(),
            "line 1: truth \"2\": expected 0 or 1"
        );
        let denominator = good.replacen("0,1,0,1,0,1,0", "0,1,0,1,0,3,0", 1);
        assert_eq!(
            parse_query_file(&denominator).unwrap_err().to_string(),
            "line 1: z denominator \"3\": not a power of two"
        );
    }
}
