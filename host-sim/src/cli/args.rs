//! A small command-line parser: `--flag value`, `--flag=value` and `--switch`, each flag at most
//! once, `-h`/`--help` anywhere. Every problem is a [`UsageError`] that names the flag.

use std::ffi::{OsStr, OsString};
use std::fmt;
use std::path::PathBuf;

/// A problem with the command line. Displays as `subject: problem`, for example
/// `--window: must be odd and between 3 and 63 (got 20)`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsageError {
    /// The flag, argument or command at fault.
    pub subject: String,
    /// What is wrong with it.
    pub problem: String,
}

impl UsageError {
    /// A problem with `subject`.
    pub fn new(subject: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            subject: subject.into(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.subject, self.problem)
    }
}

impl std::error::Error for UsageError {}

/// A flag a command accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Flag {
    /// The flag with its dashes, for example `--window`.
    pub name: &'static str,
    /// Whether the flag is followed by a value (`--window 21`) or stands alone (`--reference`).
    pub takes_value: bool,
}

impl Flag {
    /// A flag followed by a value.
    pub const fn value(name: &'static str) -> Self {
        Self {
            name,
            takes_value: true,
        }
    }

    /// A flag that stands alone.
    pub const fn switch(name: &'static str) -> Self {
        Self {
            name,
            takes_value: false,
        }
    }
}

/// What the command line asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Parsed {
    /// `-h` or `--help` was given: print the usage and do nothing else.
    Help,
    /// The flags given, each at most once.
    Flags(Matches),
}

/// Parses `args` (the words after the command name) against the flags a command accepts.
///
/// Positional arguments are accepted only when `positionals` allows that many.
pub fn parse(args: &[OsString], flags: &[Flag], positionals: usize) -> Result<Parsed, UsageError> {
    if args.iter().any(|a| a == "-h" || a == "--help") {
        return Ok(Parsed::Help);
    }
    let mut matches = Matches::default();
    let mut words = args.iter();
    while let Some(word) = words.next() {
        let Some(text) = word.to_str().filter(|t| t.starts_with('-') && *t != "-") else {
            if matches.positionals.len() == positionals {
                let problem = "unexpected argument (flags start with --)";
                return Err(UsageError::new(
                    format!("'{}'", word.to_string_lossy()),
                    problem,
                ));
            }
            matches.positionals.push(word.clone());
            continue;
        };
        let (name, attached) = match text.split_once('=') {
            Some((name, value)) => (name, Some(OsString::from(value))),
            None => (text, None),
        };
        let flag = flags
            .iter()
            .find(|f| f.name == name)
            .ok_or_else(|| UsageError::new(name, "unknown flag"))?;
        if matches.values.iter().any(|(given, _)| *given == flag.name) {
            return Err(UsageError::new(name, "given more than once"));
        }
        let value = match (flag.takes_value, attached) {
            (true, Some(value)) => Some(value),
            (true, None) => Some(flag_value(flag, words.next())?),
            (false, None) => None,
            (false, Some(_)) => return Err(UsageError::new(name, "takes no value")),
        };
        matches.values.push((flag.name, value));
    }
    Ok(Parsed::Flags(matches))
}

/// The word after a flag that needs a value. A word that looks like a flag is not taken as the
/// value: `--out --window 5` most likely lost the output path.
fn flag_value(flag: &Flag, next: Option<&OsString>) -> Result<OsString, UsageError> {
    match next {
        Some(value) if !value.to_string_lossy().starts_with("--") => Ok(value.clone()),
        _ => Err(UsageError::new(flag.name, "needs a value")),
    }
}

/// A rule a numeric flag's value must satisfy, with the words that explain it.
#[derive(Debug, Clone, Copy)]
pub struct Rule<T> {
    /// True for acceptable values.
    pub accepts: fn(T) -> bool,
    /// The rule in words, completing "--flag: ...", e.g. "must be at least 1".
    pub says: &'static str,
}

/// The flags found on a command line.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Matches {
    /// Each flag given, with its value for flags that take one.
    values: Vec<(&'static str, Option<OsString>)>,
    positionals: Vec<OsString>,
}

impl Matches {
    /// The value of `flag`, if given.
    pub fn value(&self, flag: &str) -> Option<&OsStr> {
        self.values
            .iter()
            .find(|(name, _)| *name == flag)
            .and_then(|(_, value)| value.as_deref())
    }

    /// True when the switch `flag` was given.
    pub fn switch(&self, flag: &str) -> bool {
        self.values.iter().any(|(name, _)| *name == flag)
    }

    /// The positional arguments, in order.
    pub fn positionals(&self) -> &[OsString] {
        &self.positionals
    }

    /// The path given to `flag`, if any.
    pub fn path(&self, flag: &str) -> Option<PathBuf> {
        self.value(flag).map(PathBuf::from)
    }

    /// The path given to `flag`, which must be present.
    pub fn required_path(&self, flag: &'static str) -> Result<PathBuf, UsageError> {
        match self.value(flag) {
            Some(value) if !value.is_empty() => Ok(PathBuf::from(value)),
            Some(_) => Err(UsageError::new(flag, "must not be empty")),
            None => Err(UsageError::new(flag, "is required")),
        }
    }

    /// The whole number given to `flag`, or `default`, checked against `rule`.
    pub fn integer(
        &self,
        flag: &'static str,
        default: i64,
        rule: Rule<i64>,
    ) -> Result<i64, UsageError> {
        let Some(raw) = self.value(flag) else {
            return Ok(default);
        };
        let text = raw.to_string_lossy();
        let value: i64 = text.trim().parse().map_err(|_| {
            UsageError::new(flag, format!("expected a whole number (got \"{text}\")"))
        })?;
        check(flag, value, rule)
    }

    /// The value of `flag` among the named `choices`, if given: "must be a, b or c (got x)"
    /// otherwise.
    ///
    /// ```
    /// use host_sim::cli::args::{parse, Flag, Parsed};
    /// let args = ["--model", "affine"].map(std::ffi::OsString::from);
    /// let Ok(Parsed::Flags(m)) = parse(&args, &[Flag::value("--model")], 0) else { panic!() };
    /// assert_eq!(m.choice("--model", &[("plain", 0), ("affine", 1)]), Ok(Some(1)));
    /// assert_eq!(m.choice("--other", &[("plain", 0)]), Ok(None));
    /// let e = m.choice("--model", &[("a", 0), ("b", 1), ("c", 2)]).unwrap_err();
    /// assert_eq!(e.to_string(), "--model: must be a, b or c (got affine)");
    /// ```
    pub fn choice<T: Copy>(
        &self,
        flag: &'static str,
        choices: &[(&str, T)],
    ) -> Result<Option<T>, UsageError> {
        let Some(raw) = self.value(flag) else {
            return Ok(None);
        };
        if let Some(&(_, value)) = choices.iter().find(|(name, _)| raw == *name) {
            return Ok(Some(value));
        }
        let names: Vec<&str> = choices.iter().map(|(name, _)| *name).collect();
        let listed = match names.split_last() {
            Some((last, [])) => (*last).to_string(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        };
        let got = raw.to_string_lossy();
        Err(UsageError::new(
            flag,
            format!("must be {listed} (got {got})"),
        ))
    }

    /// The decimal number given to `flag`, or `default`, checked against `rule`.
    pub fn number(
        &self,
        flag: &'static str,
        default: f64,
        rule: Rule<f64>,
    ) -> Result<f64, UsageError> {
        let Some(raw) = self.value(flag) else {
            return Ok(default);
        };
        let text = raw.to_string_lossy();
        let value: f64 = text
            .trim()
            .parse()
            .map_err(|_| UsageError::new(flag, format!("expected a number (got \"{text}\")")))?;
        check(flag, value, rule)
    }
}

fn check<T: Copy + fmt::Display>(
    flag: &'static str,
    value: T,
    rule: Rule<T>,
) -> Result<T, UsageError> {
    if (rule.accepts)(value) {
        Ok(value)
    } else {
        Err(UsageError::new(
            flag,
            format!("{} (got {value})", rule.says),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FLAGS: &[Flag] = &[
        Flag::value("--window"),
        Flag::value("--out"),
        Flag::switch("--fast"),
    ];
    const ODD: Rule<i64> = Rule {
        accepts: |n| n % 2 == 1,
        says: "must be odd",
    };

    fn words(line: &str) -> Vec<OsString> {
        line.split_whitespace().map(OsString::from).collect()
    }

    fn flags(line: &str) -> Result<Matches, UsageError> {
        match parse(&words(line), FLAGS, 0)? {
            Parsed::Flags(matches) => Ok(matches),
            Parsed::Help => panic!("unexpected help"),
        }
    }

    fn error(line: &str) -> String {
        flags(line).unwrap_err().to_string()
    }

    #[test]
    fn values_switches_and_attached_values() {
        let matches = flags("--window 5 --fast --out=o.csv").unwrap();
        assert_eq!(matches.integer("--window", 21, ODD), Ok(5));
        assert!(matches.switch("--fast"));
        assert_eq!(matches.path("--out"), Some(PathBuf::from("o.csv")));
        let defaults = flags("").unwrap();
        assert_eq!(defaults.integer("--window", 21, ODD), Ok(21));
        assert!(!defaults.switch("--fast"));
        assert_eq!(
            defaults.required_path("--out").unwrap_err().to_string(),
            "--out: is required"
        );
    }

    #[test]
    fn help_wins_anywhere() {
        assert_eq!(parse(&words("--bogus -h"), FLAGS, 0), Ok(Parsed::Help));
        assert_eq!(parse(&words("--help"), FLAGS, 0), Ok(Parsed::Help));
    }

    #[test]
    fn unknown_repeated_and_valueless_flags_are_refused() {
        assert_eq!(error("--colour red"), "--colour: unknown flag");
        assert_eq!(error("-w 5"), "-w: unknown flag");
        assert_eq!(
            error("--window 5 --window 7"),
            "--window: given more than once"
        );
        assert_eq!(error("--out"), "--out: needs a value");
        assert_eq!(error("--out --fast"), "--out: needs a value");
        assert_eq!(error("--fast=1"), "--fast: takes no value");
        assert_eq!(
            error("stray"),
            "'stray': unexpected argument (flags start with --)"
        );
    }

    #[test]
    fn numbers_are_checked_with_the_value_in_the_message() {
        assert_eq!(
            error_of_integer("--window 20"),
            "--window: must be odd (got 20)"
        );
        assert_eq!(
            error_of_integer("--window -3"),
            "--window: must be odd (got -3)"
        );
        assert_eq!(
            error_of_integer("--window abc"),
            "--window: expected a whole number (got \"abc\")"
        );
    }

    fn error_of_integer(line: &str) -> String {
        flags(line)
            .unwrap()
            .integer("--window", 21, ODD)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn a_lone_dash_and_negative_numbers_are_values() {
        let matches = parse(&words("- --window -3"), FLAGS, 1).unwrap();
        let Parsed::Flags(matches) = matches else {
            panic!("unexpected help");
        };
        assert_eq!(matches.positionals(), [OsString::from("-")]);
        assert_eq!(matches.value("--window"), Some(OsStr::new("-3")));
    }
}
