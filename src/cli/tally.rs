//! What a run adds up to: the worst failure, the counts of the summary line, the per-file lines
//! of `--verbose`, and whether `--fail-on` fails the run.

use super::outcome::Outcome;
use super::stdio::input_name;
use super::{Exit, FailOn};
use crate::scene::report::Report;
use std::path::Path;

/// The findings of warning or error severity in one report: what `--fail-on warnings` and the
/// summary count.
fn warnings_of(report: &Report) -> u64 {
    report.warnings.len() as u64
}

/// The findings `--fail-on` can name, added up over reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Findings {
    audits_disagreeing: u64,
    warnings: u64,
}

impl Findings {
    fn of(report: &Report) -> Findings {
        Findings {
            audits_disagreeing: report.summary.audits_disagreeing,
            warnings: warnings_of(report),
        }
    }

    fn add(&mut self, other: Findings) {
        self.audits_disagreeing += other.audits_disagreeing;
        self.warnings += other.warnings;
    }

    fn count(&self, finding: FailOn) -> u64 {
        match finding {
            FailOn::Audit => self.audits_disagreeing,
            FailOn::Warnings => self.warnings,
        }
    }

    /// The non-zero counts, in words: `1 audit disagrees with MikkTSpace, 2 warnings`.
    fn describe(&self, which: &[FailOn]) -> Vec<String> {
        which
            .iter()
            .filter(|&&finding| self.count(finding) > 0)
            .map(|&finding| describe_one(finding, self.count(finding)))
            .collect()
    }
}

const BOTH: [FailOn; 2] = [FailOn::Audit, FailOn::Warnings];

fn describe_one(finding: FailOn, n: u64) -> String {
    match finding {
        FailOn::Audit if n == 1 => "1 audit disagrees with MikkTSpace".to_owned(),
        FailOn::Audit => format!("{n} audits disagree with MikkTSpace"),
        FailOn::Warnings => plural(n, "warning", "warnings"),
    }
}

pub(crate) fn plural(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A run's outcomes, added up.
#[derive(Debug, Default)]
pub(crate) struct Tally {
    /// The worst failure's exit, [`Exit::Ok`] when none failed.
    pub exit: Exit,
    ok: u64,
    failed: u64,
    generated: u64,
    vertices_added: u64,
    findings: Findings,
}

impl Tally {
    pub(crate) fn of(outcomes: &[Outcome]) -> Tally {
        let mut tally = Tally::default();
        for outcome in outcomes {
            match &outcome.result {
                Ok(report) => tally.add(report),
                Err(failure) => {
                    tally.failed += 1;
                    tally.exit = tally.exit.worst(failure.exit);
                }
            }
        }
        tally
    }

    fn add(&mut self, report: &Report) {
        self.ok += 1;
        self.generated += report.summary.generated;
        self.vertices_added += report.summary.vertices_added;
        self.findings.add(Findings::of(report));
    }

    /// `tspace: 3 files ok, 0 failed; 4 primitives generated, 41 vertices added`, then the
    /// findings that are not zero.
    pub(crate) fn summary_line(&self) -> String {
        let mut line = format!(
            "tspace: {} ok, {} failed; {} generated, {} added",
            plural(self.ok, "file", "files"),
            self.failed,
            plural(self.generated, "primitive", "primitives"),
            plural(self.vertices_added, "vertex", "vertices"),
        );
        append_findings(&mut line, &self.findings.describe(&BOTH));
        line
    }

    /// The line saying why `--fail-on` fails the run, when it does:
    /// `tspace: --fail-on audit: 1 audit disagrees with MikkTSpace`.
    pub(crate) fn fail_on_line(&self, fail_on: &[FailOn]) -> Option<String> {
        let mut named: Vec<FailOn> = BOTH.into_iter().filter(|f| fail_on.contains(f)).collect();
        named.retain(|&f| self.findings.count(f) > 0);
        if named.is_empty() {
            return None;
        }
        let flags: Vec<&str> = named.iter().map(|&f| fail_on_name(f)).collect();
        Some(format!(
            "tspace: --fail-on {}: {}",
            flags.join(","),
            self.findings.describe(&named).join(", ")
        ))
    }
}

fn fail_on_name(finding: FailOn) -> &'static str {
    match finding {
        FailOn::Audit => "audit",
        FailOn::Warnings => "warnings",
    }
}

fn append_findings(line: &mut String, described: &[String]) {
    if !described.is_empty() {
        line.push_str("; ");
        line.push_str(&described.join(", "));
    }
}

/// `--verbose`: the file's counts, then one line per warning.
pub(crate) fn file_lines(path: &Path, report: &Report) -> Vec<String> {
    let name = input_name(path);
    let s = &report.summary;
    let mut counts = format!(
        "tspace: {name}: {} generated, {} audited, {} skipped, {} added",
        plural(s.generated, "primitive", "primitives"),
        s.audited,
        s.skipped,
        plural(s.vertices_added, "vertex", "vertices"),
    );
    append_findings(&mut counts, &Findings::of(report).describe(&BOTH));
    let warnings = report
        .warnings
        .iter()
        .map(|message| format!("tspace: {name}: warning: {message}"));
    std::iter::once(counts).chain(warnings).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(generated: u64, audits_disagreeing: u64, warnings: usize) -> Report {
        let mut report = Report::default();
        report.summary.generated = generated;
        report.summary.audits_disagreeing = audits_disagreeing;
        report.warnings = vec!["w".to_owned(); warnings];
        report
    }

    fn tally(reports: &[Report]) -> Tally {
        let mut tally = Tally::default();
        reports.iter().for_each(|r| tally.add(r));
        tally
    }

    #[test]
    fn the_summary_names_only_the_findings_there_are() {
        assert_eq!(
            tally(&[report(1, 0, 0)]).summary_line(),
            "tspace: 1 file ok, 0 failed; 1 primitive generated, 0 vertices added"
        );
        assert_eq!(
            tally(&[report(2, 1, 0), report(1, 0, 2)]).summary_line(),
            "tspace: 2 files ok, 0 failed; 3 primitives generated, 0 vertices added; \
             1 audit disagrees with MikkTSpace, 2 warnings"
        );
        assert_eq!(
            tally(&[report(0, 2, 1)]).summary_line(),
            "tspace: 1 file ok, 0 failed; 0 primitives generated, 0 vertices added; \
             2 audits disagree with MikkTSpace, 1 warning"
        );
    }

    #[test]
    fn fail_on_names_what_failed_the_run() {
        let run = tally(&[report(0, 1, 0)]);
        assert_eq!(run.fail_on_line(&[]), None);
        assert_eq!(run.fail_on_line(&[FailOn::Warnings]), None);
        assert_eq!(
            run.fail_on_line(&[FailOn::Warnings, FailOn::Audit])
                .as_deref(),
            Some("tspace: --fail-on audit: 1 audit disagrees with MikkTSpace")
        );
        let both = tally(&[report(0, 1, 3)]);
        assert_eq!(
            both.fail_on_line(&[FailOn::Warnings, FailOn::Audit, FailOn::Audit])
                .as_deref(),
            Some("tspace: --fail-on audit,warnings: 1 audit disagrees with MikkTSpace, 3 warnings")
        );
    }

    #[test]
    fn verbose_gives_counts_then_warnings() {
        let lines = file_lines(Path::new("a.obj"), &report(1, 0, 2));
        assert_eq!(
            lines,
            [
                "tspace: a.obj: 1 primitive generated, 0 audited, 0 skipped, 0 vertices added; 2 warnings",
                "tspace: a.obj: warning: w",
                "tspace: a.obj: warning: w",
            ]
        );
    }
}
