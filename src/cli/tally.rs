//! What a run adds up to: the worst failure, the counts of the summary line, the per-file lines
//! of `--verbose`, and whether `--fail-on` fails the run.

use super::outcome::Outcome;
use super::stdio::input_name;
use super::{Exit, FailOn};
use crate::scene::report::{Finding, Report, Severity};
use std::path::Path;

/// The findings `--fail-on` can name, added up over reports. Errors and warnings are the
/// report's own counts (`summary.findings`), so the CLI and the report never disagree on them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Findings {
    audits_disagreeing: u64,
    errors: u64,
    warnings: u64,
}

impl Findings {
    fn of(report: &Report) -> Findings {
        Findings {
            audits_disagreeing: report.summary.audits_disagreeing,
            errors: report.summary.findings.error,
            warnings: report.summary.findings.warning,
        }
    }

    fn add(&mut self, other: Findings) {
        self.audits_disagreeing += other.audits_disagreeing;
        self.errors += other.errors;
        self.warnings += other.warnings;
    }

    /// What `--fail-on` counts: `warnings` stops on a warning or anything worse.
    fn count(&self, finding: FailOn) -> u64 {
        match finding {
            FailOn::Audit => self.audits_disagreeing,
            FailOn::Warnings => self.errors + self.warnings,
        }
    }

    /// The non-zero counts, in words: `1 audit disagrees with MikkTSpace, 1 error, 2 warnings`.
    fn describe(&self, which: &[FailOn]) -> Vec<String> {
        let mut words = Vec::new();
        for finding in which {
            match finding {
                FailOn::Audit => match self.audits_disagreeing {
                    0 => {}
                    1 => words.push("1 audit disagrees with MikkTSpace".to_owned()),
                    n => words.push(format!("{n} audits disagree with MikkTSpace")),
                },
                FailOn::Warnings => {
                    for (n, one, many) in [
                        (self.errors, "error", "errors"),
                        (self.warnings, "warning", "warnings"),
                    ] {
                        if n > 0 {
                            words.push(plural(n, one, many));
                        }
                    }
                }
            }
        }
        words
    }
}

const BOTH: [FailOn; 2] = [FailOn::Audit, FailOn::Warnings];

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

/// `--verbose`: the file's counts, then one line per finding of warning or error severity.
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
    let findings = report
        .findings
        .iter()
        .filter(|f| f.severity >= Severity::Warning)
        .map(|f| format!("tspace: {name}: {}", finding_text(f)));
    std::iter::once(counts).chain(findings).collect()
}

/// `warning: mesh 0 primitive 1: 80 triangles whose UVs have no area: ... (zero_uv_area_triangles)`.
fn finding_text(finding: &Finding) -> String {
    let severity = match finding.severity {
        Severity::Error => "error",
        Severity::Warning => "warning",
        Severity::Info => "info",
    };
    let at = finding
        .primitive
        .map(|[mesh, primitive]| format!("mesh {mesh} primitive {primitive}: "))
        .unwrap_or_default();
    let count = finding.count.map(|n| format!("{n} ")).unwrap_or_default();
    format!(
        "{severity}: {at}{count}{} ({})",
        finding.message, finding.code
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::report::{DiagnosticsReport, Notice, PrimitiveReport, TallyReport};

    fn report(generated: u64, audits_disagreeing: u64, warnings: u64) -> Report {
        let mut report = Report::default();
        report.summary.generated = generated;
        report.summary.audits_disagreeing = audits_disagreeing;
        report.summary.findings.warning = warnings;
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
    fn errors_are_named_apart_and_fail_warnings_too() {
        let mut with_error = report(0, 0, 1);
        with_error.summary.findings.error = 1;
        let run = tally(&[with_error]);
        assert!(
            run.summary_line().ends_with("; 1 error, 1 warning"),
            "{}",
            run.summary_line()
        );
        assert_eq!(
            run.fail_on_line(&[FailOn::Warnings]).as_deref(),
            Some("tspace: --fail-on warnings: 1 error, 1 warning")
        );
        let mut error_only = report(0, 0, 0);
        error_only.summary.findings.error = 2;
        assert!(
            tally(&[error_only])
                .fail_on_line(&[FailOn::Warnings])
                .is_some()
        );
    }

    #[test]
    fn verbose_gives_counts_then_warnings_and_errors() {
        let mut report = Report::default();
        report.summary.generated = 1;
        report.primitives.push(PrimitiveReport {
            mesh: 0,
            primitive: 1,
            diagnostics: Some(Box::new(DiagnosticsReport {
                zero_uv_area_triangles: TallyReport {
                    count: 3,
                    first: crate::scene::report::FirstFew::new(&[0]),
                },
                mirrored_uv_triangles: TallyReport {
                    count: 7,
                    first: crate::scene::report::FirstFew::new(&[0]),
                },
                ..DiagnosticsReport::default()
            })),
            ..PrimitiveReport::default()
        });
        report.notices = vec![Notice::new("image_not_supplied", "images[0] is missing")];
        report.finish();
        let lines = file_lines(Path::new("a.obj"), &report);
        assert_eq!(lines.len(), 3, "{lines:#?}");
        assert_eq!(
            lines[0],
            "tspace: a.obj: 1 primitive generated, 0 audited, 0 skipped, 0 vertices added; 2 warnings"
        );
        assert!(
            lines[1]
                .starts_with("tspace: a.obj: warning: mesh 0 primitive 1: 3 triangles whose UVs")
                && lines[1].ends_with(" (zero_uv_area_triangles)"),
            "{}",
            lines[1]
        );
        assert_eq!(
            lines[2],
            "tspace: a.obj: warning: images[0] is missing (image_not_supplied)"
        );
    }
}
