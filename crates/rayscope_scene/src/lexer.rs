//! Line splitting, tokenising and number parsing for the scene format.
//!
//! Tokens are split on whitespace, commas, double quotes and parentheses, exactly as the course's
//! reader does (so quoted names cannot contain spaces). As extensions, a `#` at the start of a
//! token begins a comment, and parentheses are remembered so that a vector with the wrong number
//! of components can be reported clearly.

/// Splits text into lines at `\n`, `\r\n` or a lone `\r` (like .NET's `ReadLine`).
pub(crate) fn lines(src: &str) -> impl Iterator<Item = &str> {
    let mut rest = Some(src);
    std::iter::from_fn(move || {
        let text = rest?;
        // By bytes, many at a time (`memchr`): a search for either of two chars decodes the text
        // char by char, which was a fifth of the time spent parsing a large OBJ file. Both are
        // ASCII, so a byte match is a char boundary.
        match memchr::memchr2(b'\n', b'\r', text.as_bytes()) {
            Some(i) => {
                let skip = if text[i..].starts_with("\r\n") { 2 } else { 1 };
                rest = Some(&text[i + skip..]);
                Some(&text[..i])
            }
            None => {
                rest = None;
                // A final newline does not start another (empty) line.
                (!text.is_empty()).then_some(text)
            }
        }
    })
}

/// One token of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Token<'a> {
    /// The token's text.
    pub text: &'a str,
    /// Byte offset of the token's first character in the line.
    pub start: usize,
    /// Byte offset just past the token.
    pub end: usize,
    /// The balanced parenthesised group the token is in, if any (index into [`Line::groups`]).
    pub group: Option<usize>,
}

/// A `( … )` group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Group {
    /// Byte offset of the `(`.
    pub open: usize,
    /// Byte offset of the `)`, if the group was closed.
    pub close: Option<usize>,
    /// Number of tokens inside.
    pub count: usize,
}

/// A tokenised line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Line<'a> {
    /// The tokens, comment excluded.
    pub tokens: Vec<Token<'a>>,
    /// Parenthesised groups; only closed groups are referenced by tokens.
    pub groups: Vec<Group>,
    /// Byte offset just past the last character that is neither whitespace nor comment.
    pub content_end: usize,
    /// The first quoted text that the separators split into several tokens, as a byte range
    /// including the quotes (a name with a space in it, most likely).
    pub split_quote: Option<(usize, usize)>,
    /// Byte offset of the first quote, `(` or `)` that has no partner on the line.
    pub unbalanced: Option<(usize, char)>,
    /// Tokens past [`MAX_TOKENS`], counted but not kept.
    pub dropped: usize,
}

/// Most tokens (and parenthesised groups) kept for one line. The longest command has a dozen;
/// the rest can only be reported as extra, so a line of millions of words costs no more memory
/// than its text.
pub(crate) const MAX_TOKENS: usize = 256;

fn is_separator(c: char) -> bool {
    c.is_whitespace() || matches!(c, ',' | '"' | '(' | ')')
}

/// Tokenises one line (without its line ending).
pub(crate) fn lex_line<'a>(line: &'a str) -> Line<'a> {
    let mut tokens: Vec<Token<'a>> = Vec::new();
    let mut groups: Vec<Group> = Vec::new();
    let mut open_group: Option<usize> = None;
    let mut token_start: Option<usize> = None;
    let mut content_end = 0;
    let mut quote: Option<(usize, usize)> = None; // (byte of the opening quote, tokens before it)
    let mut split_quote = None;
    let mut stray_close: Option<usize> = None;

    let mut dropped = 0;
    let mut push = |tokens: &mut Vec<Token<'a>>, start: usize, end: usize, group: Option<usize>| {
        if tokens.len() == MAX_TOKENS {
            dropped += 1;
            return;
        }
        tokens.push(Token {
            text: &line[start..end],
            start,
            end,
            group,
        });
    };

    for (i, c) in line.char_indices() {
        if is_separator(c) {
            if let Some(start) = token_start.take() {
                push(&mut tokens, start, i, open_group);
                if let Some(g) = open_group {
                    groups[g].count += 1;
                }
            }
            match c {
                '(' if groups.len() < MAX_TOKENS => {
                    groups.push(Group {
                        open: i,
                        close: None,
                        count: 0,
                    });
                    open_group = Some(groups.len() - 1);
                }
                '(' => open_group = None,
                ')' => {
                    if let Some(g) = open_group.take() {
                        groups[g].close = Some(i);
                    } else if stray_close.is_none() {
                        stray_close = Some(i);
                    }
                }
                '"' => match quote.take() {
                    None => quote = Some((i, tokens.len())),
                    Some((open, before)) => {
                        if tokens.len() > before + 1 && split_quote.is_none() {
                            split_quote = Some((open, i + 1));
                        }
                    }
                },
                _ => {}
            }
            if !c.is_whitespace() {
                content_end = i + c.len_utf8();
            }
        } else {
            if token_start.is_none() {
                if c == '#' {
                    break;
                }
                token_start = Some(i);
            }
            content_end = i + c.len_utf8();
        }
    }
    if let Some(start) = token_start {
        let end = content_end.max(start);
        push(&mut tokens, start, end, open_group);
        if let Some(g) = open_group {
            groups[g].count += 1;
        }
    }
    // Tokens in groups that were never closed are treated as ungrouped.
    for t in &mut tokens {
        if t.group.is_some_and(|g| groups[g].close.is_none()) {
            t.group = None;
        }
    }
    // The earliest partnerless separator: an open quote, a group never closed, a stray `)`.
    let unbalanced = [
        quote.map(|(open, _)| (open, '"')),
        groups.iter().find(|g| g.close.is_none()).map(|g| (g.open, '(')),
        stray_close.map(|i| (i, ')')),
    ]
    .into_iter()
    .flatten()
    .min();
    Line {
        tokens,
        groups,
        content_end,
        split_quote,
        unbalanced,
        dropped,
    }
}

/// 1-based character column of byte offset `byte` in `line`.
pub(crate) fn column(line: &str, byte: usize) -> usize {
    line.get(..byte)
        .map_or_else(|| line.chars().count(), |s| s.chars().count())
        + 1
}

/// Character length of `line[start..end]`.
pub(crate) fn char_len(line: &str, start: usize, end: usize) -> usize {
    line.get(start..end).map_or(1, |s| s.chars().count())
}

/// Why a token is not an acceptable number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum NumberError {
    /// Not a number at all.
    Malformed,
    /// `NaN`, `Infinity` and friends.
    NotFinite,
    /// Syntactically a number, but too large for a double.
    Overflow,
}

/// Parses a number as C#'s `double.Parse` does with the invariant culture (optional sign,
/// digits with an optional decimal point, optional exponent), rejecting non-finite values.
pub(crate) fn parse_number(text: &str) -> Result<f64, NumberError> {
    let bytes = text.as_bytes();
    let mut i = 0;
    if matches!(bytes.first(), Some(b'+' | b'-')) {
        i += 1;
    }
    let body = &text[i..];
    // Compared in place: a lowercased copy allocated for every number read.
    if ["nan", "inf", "infinity"].iter().any(|w| body.eq_ignore_ascii_case(w)) || body == "∞" {
        return Err(NumberError::NotFinite);
    }
    let digits = |i: &mut usize| {
        let from = *i;
        while bytes.get(*i).is_some_and(u8::is_ascii_digit) {
            *i += 1;
        }
        *i - from
    };
    let mut mantissa = digits(&mut i);
    if bytes.get(i) == Some(&b'.') {
        i += 1;
        mantissa += digits(&mut i);
    }
    if mantissa == 0 {
        return Err(NumberError::Malformed);
    }
    if matches!(bytes.get(i), Some(b'e' | b'E')) {
        i += 1;
        if matches!(bytes.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        if digits(&mut i) == 0 {
            return Err(NumberError::Malformed);
        }
    }
    if i != bytes.len() {
        return Err(NumberError::Malformed);
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(NumberError::Overflow),
        Err(_) => Err(NumberError::Malformed),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texts<'a>(line: &Line<'a>) -> Vec<&'a str> {
        line.tokens.iter().map(|t| t.text).collect()
    }

    #[test]
    fn a_line_of_millions_of_words_keeps_a_bounded_number_of_tokens() {
        let text = format!("Sphere {}", "(7) ".repeat(1 << 20));
        let line = lex_line(&text);
        assert_eq!(line.tokens.len(), MAX_TOKENS);
        assert_eq!(line.groups.len(), MAX_TOKENS);
        assert_eq!(line.tokens.len() + line.dropped, (1 << 20) + 1);
        assert_eq!(line.content_end, text.trim_end().len());
    }

    #[test]
    fn partnerless_quotes_and_parentheses_are_found() {
        assert_eq!(lex_line("A \"b (1, 2) \"c\"").unbalanced, Some((14, '"')));
        assert_eq!(lex_line("A \"b\" (1, 2").unbalanced, Some((6, '(')));
        assert_eq!(lex_line("A \"b\" (1, 2))").unbalanced, Some((12, ')')));
        assert_eq!(lex_line("A \"b\" (1, 2) # \" ( in a comment").unbalanced, None);
    }

    #[test]
    fn splits_lines_like_readline() {
        let v: Vec<&str> = lines("a\r\nb\rc\n\nd\n").collect();
        assert_eq!(v, ["a", "b", "c", "", "d"]);
        assert_eq!(lines("").count(), 0);
        assert_eq!(lines("x").collect::<Vec<_>>(), ["x"]);
    }

    #[test]
    fn splits_on_separators() {
        let l = lex_line(r#"Material "Red" Diffuse (1, .5, .5) 1"#);
        assert_eq!(texts(&l), ["Material", "Red", "Diffuse", "1", ".5", ".5", "1"]);
        assert_eq!(l.tokens[1].start, 10);
        assert_eq!(l.tokens[1].end, 13);
        assert_eq!(l.tokens[3].group, Some(0));
        assert_eq!(l.tokens[6].group, None);
        assert_eq!(l.groups[0].count, 3);
        assert_eq!(l.split_quote, None);
    }

    #[test]
    fn tabs_and_odd_spacing() {
        let l = lex_line("\tSphere\t\"S\"(0,0,2) .5\"M\"  ");
        assert_eq!(texts(&l), ["Sphere", "S", "0", "0", "2", ".5", "M"]);
        assert_eq!(l.content_end, "\tSphere\t\"S\"(0,0,2) .5\"M\"".len());
    }

    #[test]
    fn comments_start_at_token_start() {
        let l = lex_line("Sphere a#b # the rest (1, 2");
        assert_eq!(texts(&l), ["Sphere", "a#b"]);
        assert_eq!(l.content_end, 10);
        assert!(lex_line("# whole line").tokens.is_empty());
        assert!(lex_line("   ").tokens.is_empty());
    }

    #[test]
    fn unbalanced_parentheses_are_separators() {
        let l = lex_line("(1, 2, 3 ) ) (4");
        assert_eq!(texts(&l), ["1", "2", "3", "4"]);
        assert_eq!(l.tokens[0].group, Some(0));
        assert_eq!(l.tokens[3].group, None);
        let l = lex_line("((1 2) 3)");
        assert_eq!(l.tokens[0].group, Some(1));
        assert_eq!(l.tokens[2].group, None);
    }

    #[test]
    fn quoted_names_with_spaces_are_noticed() {
        let l = lex_line(r#"Material "Red Mat" Diffuse"#);
        assert_eq!(texts(&l), ["Material", "Red", "Mat", "Diffuse"]);
        assert_eq!(l.split_quote, Some((9, 18)));
        assert_eq!(lex_line(r#""a" "b""#).split_quote, None);
    }

    #[test]
    fn columns_count_characters() {
        assert_eq!(column("é x", 3), 3);
        assert_eq!(char_len("é x", 0, 2), 1);
    }

    #[test]
    fn numbers_like_csharp() {
        for (s, v) in [
            ("1", 1.0),
            ("-0", -0.0),
            (".5", 0.5),
            ("1e3", 1000.0),
            ("+2", 2.0),
            ("1.", 1.0),
            ("-1.5E-2", -0.015),
            ("007", 7.0),
        ] {
            assert_eq!(parse_number(s), Ok(v), "{s}");
        }
        assert!(parse_number("-0").unwrap().is_sign_negative());
        for s in [
            "abc", ".5.", "", ".", "-", "1e", "1e+", "0x10", "1_000", "1f", "--1", " 1",
        ] {
            assert_eq!(parse_number(s), Err(NumberError::Malformed), "{s}");
        }
        for s in ["NaN", "nan", "inf", "-Infinity", "+INF", "∞"] {
            assert_eq!(parse_number(s), Err(NumberError::NotFinite), "{s}");
        }
        assert_eq!(parse_number("1e400"), Err(NumberError::Overflow));
        assert_eq!(parse_number("1e-400"), Ok(0.0));
    }
}
