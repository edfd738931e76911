//! Parsers of the numeric command-line values of `palpa` and its tools (clap `value_parser`s): a
//! value that is not a finite number in its range is refused with a message that says what was
//! expected and what was found.

/// A finite number > 0.
pub fn positive(text: &str) -> Result<f64, String> {
    number(text, "> 0", |x| x > 0.0)
}

/// A finite number ≥ 0.
pub fn non_negative(text: &str) -> Result<f64, String> {
    number(text, "≥ 0", |x| x >= 0.0)
}

/// A whole number ≥ 1.
pub fn count(text: &str) -> Result<u64, String> {
    match text.trim().parse::<u64>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("must be a whole number ≥ 1, found {text}")),
    }
}

fn number(text: &str, range: &str, within: impl Fn(f64) -> bool) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && within(x) => Ok(x),
        _ => Err(format!("must be a finite number {range}, found {text}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_what_is_out_of_range_or_not_finite() {
        assert_eq!(positive("2.5"), Ok(2.5));
        for bad in ["0", "-1", "NaN", "nan", "inf", "-inf", "1e999", "x", ""] {
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(non_negative("-0.1").is_err());
        assert!(non_negative("NaN").is_err());
        assert_eq!(count("3"), Ok(3));
        for bad in ["0", "-1", "1.5", "NaN"] {
            assert!(count(bad).is_err(), "{bad}");
        }
    }
}
