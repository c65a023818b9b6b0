//! The progress bar of a run: on stderr when it is a terminal, one line that fits 80 columns,
//! naming the file being read with its path shortened in the middle so its name stays whole.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::Path;

/// The line is sized for the narrowest terminal in common use, not measured: a narrower one
/// wraps, a wider one has room to spare.
const LINE_COLUMNS: usize = 80;
const BAR_COLUMNS: usize = 20;
/// `{elapsed}` is compact (`7s`, `12m`, `3h`).
const ELAPSED_COLUMNS: usize = 4;
/// Below this a shortened path says too little to be worth the clutter.
const MIN_NAME_COLUMNS: usize = 12;
const ELLIPSIS: char = '…';

pub(crate) struct Progress {
    bar: ProgressBar,
    name_columns: usize,
}

impl Progress {
    /// A bar for `files` files, drawn only when `shown` and stderr is a terminal.
    pub(crate) fn new(files: usize, shown: bool) -> Progress {
        let name_columns = name_columns(files);
        if files == 0 || !shown || !std::io::stderr().is_terminal() {
            return Progress {
                bar: ProgressBar::hidden(),
                name_columns,
            };
        }
        let bar = ProgressBar::new(files as u64);
        let template = format!(
            "{{bar:{BAR_COLUMNS}}} {{pos}}/{{len}} files  {{elapsed:>{ELAPSED_COLUMNS}}}  {{msg}}"
        );
        if let Ok(style) = ProgressStyle::with_template(&template) {
            bar.set_style(style);
        }
        Progress { bar, name_columns }
    }

    pub(crate) fn start(&self, path: &Path) {
        if !self.bar.is_hidden() {
            let shown = path.to_string_lossy();
            self.bar
                .set_message(shorten_middle(&shown, self.name_columns));
        }
    }

    pub(crate) fn done(&self) {
        self.bar.inc(1);
    }

    pub(crate) fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// What is left of the line for the file name, once the bar, `pos/len files` and the elapsed
/// time have theirs (and one column spare, so the cursor never wraps).
fn name_columns(files: usize) -> usize {
    let digits = files.max(1).to_string().len();
    let fixed = BAR_COLUMNS + 1 + (2 * digits + 1) + " files  ".len() + ELAPSED_COLUMNS + 2;
    LINE_COLUMNS.saturating_sub(fixed + 1).max(MIN_NAME_COLUMNS)
}

/// `text` in at most `max_chars` characters: whole when it fits, else its start and its end
/// around an ellipsis. The end, the file name, is kept whole when it fits, and the start gets at
/// most a third (`mod…/SciFiHelmet.gltf`); a name longer than the room keeps its end
/// (`…iFiHelmet.gltf`). Counted in chars, so a multi-byte name is never cut inside a character.
pub(crate) fn shorten_middle(text: &str, max_chars: usize) -> String {
    let chars: Vec<char> = text.chars().collect();
    if chars.len() <= max_chars {
        return text.to_owned();
    }
    let Some(room) = max_chars.checked_sub(1) else {
        return String::new();
    };
    let name_chars = chars
        .iter()
        .rev()
        .position(|&c| c == '/' || c == '\\')
        .map_or(chars.len(), |from_end| from_end + 1);
    let head = (room / 3).min(room.saturating_sub(name_chars));
    let tail = room - head;
    let mut shortened: String = chars[..head].iter().collect();
    shortened.push(ELLIPSIS);
    shortened.extend(&chars[chars.len() - tail..]);
    shortened
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_that_fits_is_left_alone() {
        assert_eq!(shorten_middle("a/b.glb", 7), "a/b.glb");
        assert_eq!(shorten_middle("", 3), "");
    }

    #[test]
    fn the_middle_goes_and_the_file_name_stays() {
        let path = "models/SciFiHelmet/glTF/SciFiHelmet.gltf";
        assert_eq!(shorten_middle(path, 21), "mod…/SciFiHelmet.gltf");
        assert_eq!(shorten_middle(path, 30), "models/Sc…lTF/SciFiHelmet.gltf");
    }

    #[test]
    fn a_long_name_keeps_its_end() {
        assert_eq!(
            shorten_middle("dir/AVeryLongSceneName.gltf", 10),
            "…Name.gltf"
        );
        assert_eq!(shorten_middle("AVeryLongSceneName.gltf", 6), "….gltf");
        assert_eq!(shorten_middle("abc", 1), "…");
        assert_eq!(shorten_middle("abc", 0), "");
    }

    #[test]
    fn characters_are_counted_not_bytes() {
        let path = "モデル/ヘルメット/日本語のシーン.glb";
        let short = shorten_middle(path, 16);
        assert_eq!(short.chars().count(), 16);
        assert!(short.ends_with("/日本語のシーン.glb"), "{short}");
        assert!(short.starts_with("モデル…"), "{short}");
        let windows = shorten_middle(r"C:\scenes\deep\folder\Box.glb", 12);
        assert_eq!(windows, r"C:\…\Box.glb");
    }

    #[test]
    fn the_line_fits_80_columns() {
        for files in [1, 9, 10, 999, 100_000] {
            let digits = files.to_string().len();
            let fixed = BAR_COLUMNS + 1 + (2 * digits + 1) + 8 + ELAPSED_COLUMNS + 2;
            assert!(fixed + name_columns(files) < LINE_COLUMNS, "{files}");
        }
    }
}
