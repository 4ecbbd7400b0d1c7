//! Notes at a readable width: a front end prints a job's notes (fallbacks, decisions) as
//! lines of at most [`NOTE_WIDTH`] characters, so a note that names many places or
//! parameters does not run to hundreds of characters on one line.

/// The widest line of a printed note, in characters (a word longer than this, such as a
/// long path, is kept whole on its own line).
pub const NOTE_WIDTH: usize = 100;

/// `text` broken at spaces into lines of at most `width` characters (a longer word stays
/// whole), every line after the first starting with `indent`; the words and their order
/// are kept, runs of spaces become one.
pub fn wrap(text: &str, width: usize, indent: &str) -> String {
    let mut out =
        String::with_capacity(text.len() + text.len() / width.max(1) * (indent.len() + 1));
    let mut line = 0usize;
    for word in text.split_whitespace() {
        let n = word.chars().count();
        if line > 0 && line + 1 + n > width {
            out.push('\n');
            out.push_str(indent);
            line = indent.chars().count();
        } else if line > 0 {
            out.push(' ');
            line += 1;
        }
        out.push_str(word);
        line += n;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every line fits, no word is lost or split, and short text is unchanged.
    #[test]
    fn lines_fit_and_words_are_kept() {
        let text = "note: ".to_string() + &"pixels of one tile pinned to zero ".repeat(20);
        let wrapped = wrap(&text, NOTE_WIDTH, "      ");
        assert!(wrapped.lines().count() > 5);
        for line in wrapped.lines() {
            assert!(line.chars().count() <= NOTE_WIDTH, "{line}");
        }
        let words = |s: &str| s.split_whitespace().map(str::to_string).collect::<Vec<_>>();
        assert_eq!(words(&wrapped), words(&text));
        assert_eq!(wrap("a short note", NOTE_WIDTH, "  "), "a short note");
        let long = "x".repeat(150);
        assert_eq!(
            wrap(&format!("see {long} here"), 20, ""),
            format!("see\n{long}\nhere")
        );
    }
}
