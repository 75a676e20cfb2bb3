//! Logging: where an instance's messages go, and which of them the importer asked for.

use super::status::Status;
use std::ffi::{CStr, CString};

/// Where an instance's messages go: the logger the importer gave at instantiation, in the form of the
/// protocol it instantiated with (each layer implements it for its callback and codes the status itself).
pub trait Logger {
    fn log(&self, instance: &CStr, status: Status, category: &str, text: &str);
}

/// Log categories the instance can switch on.
#[derive(Debug, Clone, Copy)]
pub struct LogSwitches {
    pub errors: bool,
    pub discards: bool,
    pub warnings: bool,
    pub calls: bool,
}

impl Default for LogSwitches {
    /// At instantiation: refusals, discards and warnings are logged, calls are not.
    fn default() -> Self {
        Self {
            errors: true,
            discards: true,
            warnings: true,
            calls: false,
        }
    }
}

impl LogSwitches {
    /// The switches the importer asks for with logging `on` and `categories` (none, or `logAll`, means all),
    /// or why not: a category the model does not declare in `known`. `logStatusError` stays on whatever is
    /// asked: refusals always carry their reason.
    pub fn requested(on: bool, categories: &[String], known: &[&str]) -> Result<Self, String> {
        for c in categories {
            if !known.contains(&c.as_str()) {
                return Err(format!(
                    "unknown log category '{c}' (declared: {})",
                    known.join(", ")
                ));
            }
        }
        let all = categories.is_empty() || categories.iter().any(|c| c == "logAll");
        let has = |n: &str| all || categories.iter().any(|c| c == n);
        Ok(Self {
            errors: true,
            discards: !on || has("logStatusDiscard"),
            warnings: !on || has("logStatusWarning"),
            calls: on && has("logCalls"),
        })
    }
}

/// `text` as a C string (an interior NUL becomes a space).
pub fn cstring(text: &str) -> CString {
    CString::new(text.replace('\0', " ")).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With logging on, the categories asked for are on (none or `logAll`: all); with logging off, the
    /// defaults stay (discards and warnings, not calls); refusals are logged either way; a category the
    /// model does not declare is refused by name.
    #[test]
    fn the_switches_follow_the_categories_asked_for() {
        let known = [
            "logStatusWarning",
            "logStatusDiscard",
            "logStatusError",
            "logCalls",
            "logAll",
        ];
        let ask = |on, categories: &[&str]| {
            let categories: Vec<String> = categories.iter().map(|c| c.to_string()).collect();
            LogSwitches::requested(on, &categories, &known)
                .map(|s| (s.errors, s.discards, s.warnings, s.calls))
        };
        let all = (true, true, true, true);
        assert_eq!(
            ask(true, &["logStatusWarning"]),
            Ok((true, false, true, false))
        );
        assert_eq!(
            ask(true, &["logStatusDiscard", "logCalls"]),
            Ok((true, true, false, true))
        );
        assert_eq!(
            ask(true, &["logStatusError"]),
            Ok((true, false, false, false))
        );
        assert_eq!((ask(true, &[]), ask(true, &["logAll"])), (Ok(all), Ok(all)));
        let defaults = Ok((true, true, true, false));
        assert_eq!(ask(false, &["logStatusWarning"]), defaults);
        assert_eq!(ask(false, &["logCalls"]), defaults);
        assert_eq!(ask(false, &[]), defaults);
        let refused = ask(true, &["logEvents"]).unwrap_err();
        assert!(
            refused.contains("unknown log category 'logEvents'"),
            "{refused}"
        );
    }
}
