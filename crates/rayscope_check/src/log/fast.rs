//! A reader for the common shape of a ray record: parsing is most of the time of checking a
//! large log, and this reader takes less of it than serde_json's generic deserialiser (the
//! measurement is in docs/check.md).
//!
//! It accepts only what it can read exactly as serde_json would: strings without escapes or
//! control characters, numbers in JSON's grammar (integers where the field is an integer), each
//! field at most once, and nothing after the object. Anything else returns `None`, and the record
//! is read by serde_json, which also words the error when the record is malformed.

use std::borrow::Cow;

use wide::{f64x4, u8x16};

use super::raw::{BlockerRef, LightRef, RawHit, RawRay};

mod shape;

pub(super) use shape::{ray, Names};

/// A position in one record. Only strings can hold bytes outside ASCII (everything else must
/// be JSON's punctuation, literals and numbers), so each string is checked to be UTF-8 on its
/// own, and only when it has such a byte.
struct Cursor<'a> {
    b: &'a [u8],
    i: usize,
}

/// A key of up to 16 bytes as one integer, so that a field is found by one comparison.
const fn key(k: &[u8]) -> u128 {
    let mut v = 0u128;
    let mut j = 0;
    while j < k.len() {
        v |= (k[j] as u128) << (8 * j);
        j += 1;
    }
    v | ((k.len() as u128) << 120)
}

/// A key as a record spells it when written without spaces: `"name":`, as sixteen bytes masked
/// to its length, so that a key where it is expected is recognised by one comparison.
struct Known {
    key: u128,
    text: u128,
    mask: u128,
    len: usize,
}

impl Known {
    const fn new(k: &[u8]) -> Known {
        let len = k.len() + 3;
        assert!(len <= 16, "a key the reader expects fits in sixteen bytes");
        let mut text = b'"' as u128;
        let mut j = 0;
        while j < k.len() {
            text |= (k[j] as u128) << (8 * (j + 1));
            j += 1;
        }
        text |= (b'"' as u128) << (8 * (k.len() + 1));
        text |= (b':' as u128) << (8 * (k.len() + 2));
        let mask = if len == 16 { u128::MAX } else { (1u128 << (8 * len)) - 1 };
        Known {
            key: key(k),
            text,
            mask,
            len,
        }
    }
}

/// A text of one to sixteen bytes (none of them 0) expected at a place in a record, as sixteen
/// bytes masked to its length, so that it is recognised by one comparison ([`Cursor::lit16`]).
pub(super) struct Lit {
    text: u128,
    mask: u128,
    len: usize,
}

impl Lit {
    const fn new(t: &[u8]) -> Lit {
        assert!(
            !t.is_empty() && t.len() <= 16,
            "a text compared at once fits in sixteen bytes"
        );
        let mut text = 0u128;
        let mut j = 0;
        while j < t.len() {
            assert!(t[j] != 0, "past its end a record reads as zero bytes");
            text |= (t[j] as u128) << (8 * j);
            j += 1;
        }
        let mask = if t.len() == 16 {
            u128::MAX
        } else {
            (1u128 << (8 * t.len())) - 1
        };
        Lit {
            text,
            mask,
            len: t.len(),
        }
    }
}

impl<'a> Cursor<'a> {
    #[inline]
    fn skip_ws(&mut self) {
        while let Some(&c) = self.b.get(self.i) {
            if matches!(c, b' ' | b'\t' | b'\n' | b'\r') {
                self.i += 1;
            } else {
                break;
            }
        }
    }

    #[inline]
    fn peek(&mut self) -> Option<u8> {
        match self.b.get(self.i) {
            Some(&c) if c > b' ' => Some(c),
            _ => {
                self.skip_ws();
                self.b.get(self.i).copied()
            }
        }
    }

    #[inline]
    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn literal(&mut self, word: &[u8]) -> bool {
        self.skip_ws();
        if self.b[self.i..].starts_with(word) {
            self.i += word.len();
            true
        } else {
            false
        }
    }

    /// The bytes of a string without escapes, and whether they are all ASCII.
    #[inline]
    fn string_bytes(&mut self) -> Option<(&'a [u8], bool)> {
        if !self.eat(b'"') {
            return None;
        }
        let b = self.b;
        let start = self.i;
        // Keys and names are a few bytes long: sixteen bytes looked at together hold most of them.
        if let Some(w) = b.get(start..start + 16) {
            let v = u8x16::new(w.try_into().expect("sixteen bytes"));
            let quote = v.simd_eq(u8x16::splat(b'"')).to_bitmask();
            if quote != 0 {
                let n = quote.trailing_zeros() as usize;
                let before = (1u32 << n) - 1;
                // Control characters are the bytes that a minimum with 0x1f leaves as they are.
                let control = v.min(u8x16::splat(0x1f)).simd_eq(v).to_bitmask();
                let backslash = v.simd_eq(u8x16::splat(b'\\')).to_bitmask();
                if (control | backslash) & before == 0 {
                    self.i = start + n + 1;
                    // A byte outside ASCII has its top bit set.
                    return Some((&b[start..start + n], v.to_bitmask() & before == 0));
                }
            }
        }
        let mut end = start;
        let mut ascii = true;
        loop {
            match *b.get(end)? {
                b'"' => break,
                b'\\' => return None,
                c if c < 0x20 => return None,
                c => {
                    ascii &= c < 0x80;
                    end += 1;
                }
            }
        }
        self.i = end + 1;
        Some((&b[start..end], ascii))
    }

    /// A string without escapes, borrowed from the record.
    #[inline]
    fn string(&mut self) -> Option<&'a str> {
        std::str::from_utf8(self.string_bytes()?.0).ok()
    }

    /// A string without escapes; the words tracers write for a ray's kind are recognised by
    /// their bytes and handed out as the same words of the program's own text.
    #[inline]
    fn word(&mut self) -> Option<Cow<'a, str>> {
        let (w, _) = self.string_bytes()?;
        Some(Cow::Borrowed(match w {
            b"camera" => "camera",
            b"shadow" => "shadow",
            b"reflection" => "reflection",
            b"refraction" => "refraction",
            _ => std::str::from_utf8(w).ok()?,
        }))
    }

    /// A key, as [`key`] packs it (longer keys, and keys outside ASCII, as 0: no field's).
    #[inline]
    fn key(&mut self) -> Option<u128> {
        let end = self.i;
        let (k, ascii) = self.string_bytes()?;
        if !ascii {
            std::str::from_utf8(k).ok()?;
        }
        if k.len() > 15 {
            return Some(0);
        }
        // The sixteen bytes from the key's first one, where the record has them, masked to the
        // key: one load instead of a loop.
        let start = self.i - 1 - k.len();
        debug_assert!(start > end);
        Some(match self.b.get(start..start + 16) {
            Some(w) => {
                let v = u128::from_le_bytes(w.try_into().expect("sixteen bytes"));
                (v & ((1u128 << (8 * k.len())) - 1)) | ((k.len() as u128) << 120)
            }
            None => key(k),
        })
    }

    /// A number in JSON's grammar, as text, and whether it has a fraction or an exponent.
    fn number(&mut self) -> Option<(&'a str, bool)> {
        self.skip_ws();
        let b = self.b;
        let start = self.i;
        let mut i = start;
        let digits = |i: &mut usize| {
            let from = *i;
            while b.get(*i).is_some_and(u8::is_ascii_digit) {
                *i += 1;
            }
            *i - from
        };
        if b.get(i) == Some(&b'-') {
            i += 1;
        }
        let int_start = i;
        let n = digits(&mut i);
        if n == 0 || (n > 1 && b[int_start] == b'0') {
            return None;
        }
        let mut real = false;
        if b.get(i) == Some(&b'.') {
            i += 1;
            if digits(&mut i) == 0 {
                return None;
            }
            real = true;
        }
        if matches!(b.get(i), Some(b'e' | b'E')) {
            i += 1;
            if matches!(b.get(i), Some(b'+' | b'-')) {
                i += 1;
            }
            if digits(&mut i) == 0 {
                return None;
            }
            real = true;
        }
        self.i = i;
        // The grammar above admits only ASCII.
        std::str::from_utf8(&b[start..i]).ok().map(|s| (s, real))
    }

    /// A decimal without an exponent whose digits, read as an integer, are at most 2^53, with at
    /// most 22 after the point: both that integer and the power of ten are exact f64s, so one
    /// division gives the correctly rounded value, which is what every exact reader returns.
    /// Tracers print most coordinates this way. `None` for anything else, read by [`Self::f64`].
    fn short_decimal(&mut self) -> Option<f64> {
        const POW10: [f64; 23] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
            1e19, 1e20, 1e21, 1e22,
        ];
        self.skip_ws();
        let b = self.b;
        let mut i = self.i;
        let negative = b.get(i) == Some(&b'-');
        if negative {
            i += 1;
        }
        let int_start = i;
        let (mut m, int_digits) = digit_run(b, &mut i, 0);
        if int_digits == 0 || (int_digits > 1 && b[int_start] == b'0') {
            return None;
        }
        let mut digits = int_digits;
        let mut fraction = 0usize;
        if b.get(i) == Some(&b'.') {
            i += 1;
            (m, fraction) = digit_run(b, &mut i, m);
            if fraction == 0 {
                return None;
            }
            digits += fraction;
        }
        // 19 digits cannot wrap a u64, so `m` is the exact integer they spell.
        if digits > 19 || m > 1 << 53 || fraction > 22 || matches!(b.get(i), Some(b'e' | b'E')) {
            return None;
        }
        let v = m as f64 / POW10[fraction];
        self.i = i;
        Some(if negative { -v } else { v })
    }

    /// The sixteen bytes from `at` ([`window`]).
    #[inline(always)]
    fn window(&self, at: usize) -> [u8; 16] {
        window(self.b, at)
    }

    /// A decimal as [`decimal`] reads it, with the cursor moved past it. Tracers print most
    /// coordinates this way. `None` for anything else.
    #[inline(always)]
    fn decimal16(&mut self) -> Option<f64> {
        let (v, end, after) = decimal(self.b, self.i)?;
        if matches!(after, b'e' | b'E') {
            return None;
        }
        self.i = end;
        Some(v)
    }

    #[inline]
    fn f64(&mut self) -> Option<f64> {
        match self.decimal16() {
            Some(v) => Some(v),
            None => self.f64_slow(),
        }
    }

    /// [`Self::f64`] for numbers [`Self::decimal16`] does not read.
    #[cold]
    #[inline(never)]
    fn f64_slow(&mut self) -> Option<f64> {
        if let Some(v) = self.short_decimal() {
            return Some(v);
        }
        let (s, _) = self.number()?;
        let v: f64 = s.parse().ok()?;
        // serde_json refuses numbers too large for an f64.
        v.is_finite().then_some(v)
    }

    /// Digits at the cursor, at most `most` of them, with no fraction or exponent after them,
    /// read at once, with the cursor moved past them: `None` (and the cursor left) for anything
    /// else.
    #[inline]
    fn plain_integer(&mut self, most: usize) -> Option<u64> {
        // Pixels, samples and ids are a few digits long: up to seven are read at once.
        let w = self.window(self.i);
        let x = u64::from_le_bytes(w[..8].try_into().expect("eight bytes")).wrapping_sub(0x3030_3030_3030_3030);
        // As in `digit_run`: the lowest byte flagged is the first that is not a digit.
        let not_digit = (x | x.wrapping_add(0x7676_7676_7676_7676)) & 0x8080_8080_8080_8080;
        let n = (not_digit.trailing_zeros() / 8) as usize;
        if n == 8 {
            return self.long_integer(most);
        }
        if n == 0 || n > most || (n > 1 && w[0] == b'0') || matches!(w[n], b'.' | b'e' | b'E') {
            return None;
        }
        self.i += n;
        // The n digits moved to the top, so that the bytes below them read as leading zeros.
        Some(eight_digits(x << (8 * (8 - n))))
    }

    /// [`Self::plain_integer`] for eight digits or more.
    #[cold]
    #[inline(never)]
    fn long_integer(&mut self, most: usize) -> Option<u64> {
        let b = self.b;
        let mut i = self.i;
        let (m, n) = digit_run(b, &mut i, 0);
        if n > most || b[self.i] == b'0' || matches!(b.get(i), Some(b'.' | b'e' | b'E')) {
            return None;
        }
        self.i = i;
        Some(m)
    }

    /// True, with the cursor moved past it, when the record has exactly `l`'s text at the
    /// cursor: one comparison of sixteen bytes.
    #[inline(always)]
    fn lit16(&mut self, l: &Lit) -> bool {
        let v = u128::from_le_bytes(self.window(self.i));
        let found = v & l.mask == l.text;
        if found {
            self.i += l.len;
        }
        found
    }

    fn u32(&mut self) -> Option<u32> {
        if let Some(m) = self.plain_integer(9) {
            // Nine digits cannot exceed a u32.
            return Some(m as u32);
        }
        match self.number()? {
            (s, false) if !s.starts_with('-') => s.parse().ok(),
            _ => None,
        }
    }

    fn i64(&mut self) -> Option<i64> {
        if let Some(m) = self.plain_integer(18) {
            // Eighteen digits cannot exceed an i64.
            return Some(m as i64);
        }
        match self.number()? {
            (s, false) if s != "-0" => s.parse().ok(),
            _ => None,
        }
    }

    fn vec3(&mut self) -> Option<[f64; 3]> {
        if !self.eat(b'[') {
            return None;
        }
        let x = self.f64()?;
        if !self.eat(b',') {
            return None;
        }
        let y = self.f64()?;
        if !self.eat(b',') {
            return None;
        }
        let z = self.f64()?;
        self.eat(b']').then_some([x, y, z])
    }

    fn pixel(&mut self) -> Option<[u32; 2]> {
        if !self.eat(b'[') {
            return None;
        }
        let x = self.u32()?;
        if !self.eat(b',') {
            return None;
        }
        let y = self.u32()?;
        self.eat(b']').then_some([x, y])
    }

    /// `null` as `Some(None)`, else the value `read` reads.
    #[inline]
    fn nullable<T>(&mut self, read: impl FnOnce(&mut Self) -> Option<T>) -> Option<Option<T>> {
        if self.peek() == Some(b'n') && self.literal(b"null") {
            Some(None)
        } else {
            read(self).map(Some)
        }
    }

    /// Skips a value of a field the record format does not use, as serde_json ignores it.
    fn skip_value(&mut self, depth: u32) -> Option<()> {
        if depth > 32 {
            return None;
        }
        match self.peek()? {
            b'"' => self.string().map(drop),
            b'{' | b'[' => {
                let close = if self.eat(b'{') {
                    b'}'
                } else {
                    self.i += 1;
                    b']'
                };
                if self.eat(close) {
                    return Some(());
                }
                loop {
                    if close == b'}' {
                        self.string()?;
                        if !self.eat(b':') {
                            return None;
                        }
                    }
                    self.skip_value(depth + 1)?;
                    if self.eat(close) {
                        return Some(());
                    }
                    if !self.eat(b',') {
                        return None;
                    }
                }
            }
            b't' => self.literal(b"true").then_some(()),
            b'f' => self.literal(b"false").then_some(()),
            b'n' => self.literal(b"null").then_some(()),
            _ => self.number().map(drop),
        }
    }

    /// The key `k` with its colon, when the record has exactly that text at the cursor.
    #[inline]
    fn known_key(&mut self, k: &Known) -> bool {
        let Some(w) = self.b.get(self.i..self.i + 16) else {
            return false;
        };
        let v = u128::from_le_bytes(w.try_into().expect("sixteen bytes"));
        let found = v & k.mask == k.text;
        if found {
            self.i += k.len;
        }
        found
    }

    /// The members of an object, each handed to `field` with the cursor on its value, by the
    /// position of its key in `order` (`None` for a key not there). Records written by one
    /// tracer list their keys in one order, most often `order` with some left out: the keys of
    /// `order` after the last one found are tried by their text, and any other key is read as a
    /// string.
    #[inline]
    fn object(&mut self, order: &[Known], mut field: impl FnMut(&mut Self, Option<usize>) -> Option<()>) -> Option<()> {
        if !self.eat(b'{') {
            return None;
        }
        if self.eat(b'}') {
            return Some(());
        }
        let mut next = 0;
        loop {
            let known = order
                .get(next..)
                .and_then(|rest| rest.iter().position(|k| self.known_key(k)));
            let at = match known {
                Some(p) => Some(next + p),
                None => {
                    let key = self.key()?;
                    if !self.eat(b':') {
                        return None;
                    }
                    order.iter().position(|k| k.key == key)
                }
            };
            if let Some(p) = at {
                next = p + 1;
            }
            field(self, at)?;
            if self.eat(b'}') {
                return Some(());
            }
            if !self.eat(b',') {
                return None;
            }
        }
    }
}

/// The sixteen bytes of `b` from `at`, with zero bytes (no digit, quote or letter) for those
/// past its end: one load where `b` has them.
#[inline(always)]
fn window(b: &[u8], at: usize) -> [u8; 16] {
    match b.get(at..at + 16) {
        Some(w) => w.try_into().expect("sixteen bytes"),
        None => window_tail(b, at),
    }
}

/// [`window`] near the end of `b`: its last sixteen bytes shifted down.
#[inline(never)]
fn window_tail(b: &[u8], at: usize) -> [u8; 16] {
    let len = b.len();
    match b.get(len.wrapping_sub(16)..) {
        Some(last) if at <= len => {
            let v = u128::from_le_bytes(last.try_into().expect("sixteen bytes"));
            // The bytes before `at` shifted out, zeros shifted in at the top.
            v.checked_shr(8 * (at + 16 - len) as u32).unwrap_or(0).to_le_bytes()
        }
        _ => {
            let mut w = [0u8; 16];
            let rest = b.get(at..).unwrap_or_default();
            let n = rest.len().min(16);
            w[..n].copy_from_slice(&rest[..n]);
            w
        }
    }
}

/// A decimal at `b[at..]` without an exponent, its sign included, at most 7 digits before its
/// point and at most 14 after, ending within the fifteen bytes after its sign: its value, where
/// it ends, and the byte after it (0 past the end of `b`), which the caller checks (a decimal
/// followed by `e` is not this one). Its digits, read as an integer, are below 10^14 < 2^53,
/// so one division gives the correctly rounded value (see [`Cursor::short_decimal`]). The
/// digits are found sixteen bytes at a time and converted eight at a time. `None` for
/// anything else.
#[inline(always)]
fn decimal(b: &[u8], at: usize) -> Option<(f64, usize, u8)> {
    let (Fraction { num, den }, end, after) = decimal_fraction(b, at)?;
    Some((num / den, end, after))
}

/// A decimal's value as the division that gives it, both sides exact: its digits, signed, over
/// the power of ten its point stands for. Dividing a negated numerator gives the negated
/// quotient (rounding to nearest is symmetric), `-0` included.
#[derive(Clone, Copy)]
struct Fraction {
    num: f64,
    den: f64,
}

/// [`decimal`] before its one division.
#[inline(always)]
fn decimal_fraction(b: &[u8], at: usize) -> Option<(Fraction, usize, u8)> {
    const POW10: [f64; 15] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14,
    ];
    let negative = b.get(at) == Some(&b'-');
    let start = at + usize::from(negative);
    let w = window(b, start);
    let v = u8x16::new(w) - u8x16::splat(b'0');
    // The digit values, and which bytes are digits.
    let first = w[0].wrapping_sub(b'0');
    let digit = v.min(u8x16::splat(9)).simd_eq(v).to_bitmask();
    let int = (!digit).trailing_zeros() as usize;
    // 1 to 7 digits before the point, without a leading zero ('0' is the digit value 0).
    if int.wrapping_sub(1) >= 7 || (int > 1 && first == 0) {
        return None;
    }
    // Eight digit values from byte `at`, the first in the lowest byte, taken from the window in a
    // register: bytes past a non-digit may be wrong (a borrow runs upward only) and are shifted
    // out by `run`. Read back from memory at a varying offset, the vector's store could not be
    // forwarded to the load, which then waits for the store to complete.
    let wide = u128::from_le_bytes(w);
    let eight = |at: usize| ((wide >> (8 * at)) as u64).wrapping_sub(0x3030_3030_3030_3030);
    // The `n` (1 to 8) digits from byte `at` moved to the top, so that the bytes below them
    // read as leading zeros.
    let run = |at: usize, n: usize| eight_digits(eight(at) << (8 * (8 - n)));
    // Most coordinates have one digit before the point.
    let mut m = if int == 1 { u64::from(first) } else { run(0, int) };
    let (frac, end) = if w[int] == b'.' {
        let f = (!(digit >> (int + 1))).trailing_zeros() as usize;
        let end = int + 1 + f;
        if f == 0 || end > 15 {
            return None;
        }
        let digits = if f <= 8 {
            run(int + 1, f)
        } else {
            // The first f − 8, then the last eight, which end where the number does.
            run(int + 1, f - 8) * POW10_U64[8] + eight_digits(eight(end - 8))
        };
        m = m * POW10_U64[f] + digits;
        (f, end)
    } else {
        (0, int)
    };
    // Below 2^53, so also as a signed integer, which converts in one instruction.
    let v = m as i64 as f64;
    let num = if negative { -v } else { v };
    Some((Fraction { num, den: POW10[frac] }, start + end, w[end]))
}

/// Three decimals as [`decimal`] reads them, in brackets, with commas and no spaces between,
/// at `b[at..]`: the numbers and where they end.
#[inline(never)]
fn tight_vec3(b: &[u8], at: usize) -> Option<([f64; 3], usize)> {
    if b.get(at) != Some(&b'[') {
        return None;
    }
    // The two commas and the bracket after them are found first, in the 48 bytes from `at`,
    // so that the three numbers are read side by side: read one after the other, each number's
    // start waits for the end of the one before it.
    let mut commas = 0u64;
    let mut closes = 0u64;
    for k in 0..3 {
        let v = u8x16::new(window(b, at + 16 * k));
        commas |= u64::from(v.simd_eq(u8x16::splat(b',')).to_bitmask()) << (16 * k);
        closes |= u64::from(v.simd_eq(u8x16::splat(b']')).to_bitmask()) << (16 * k);
    }
    let c1 = commas.trailing_zeros() as usize;
    let c2 = (commas & commas.wrapping_sub(1)).trailing_zeros() as usize;
    let close = closes.trailing_zeros() as usize;
    if close >= 48 || c2 > close {
        return tight_vec3_serial(b, at);
    }
    // A decimal holds no comma or bracket, so each one ends at its separator exactly when the
    // byte after it is that separator.
    let (x, xe, _) = decimal_fraction(b, at + 1)?;
    let (y, ye, _) = decimal_fraction(b, at + c1 + 1)?;
    let (z, ze, _) = decimal_fraction(b, at + c2 + 1)?;
    if xe != at + c1 || ye != at + c2 || ze != at + close {
        return None;
    }
    // The three divisions as one: each lane is the same correctly rounded quotient.
    let q = f64x4::new([x.num, y.num, z.num, 1.0]) / f64x4::new([x.den, y.den, z.den, 1.0]);
    let [x, y, z, _] = q.to_array();
    Some(([x, y, z], at + close + 1))
}

/// [`tight_vec3`] one number after the other, for triples longer than the bytes it looks at.
#[cold]
fn tight_vec3_serial(b: &[u8], at: usize) -> Option<([f64; 3], usize)> {
    let (x, i, after) = decimal(b, at + 1)?;
    if after != b',' {
        return None;
    }
    let (y, i, after) = decimal(b, i + 1)?;
    if after != b',' {
        return None;
    }
    let (z, i, after) = decimal(b, i + 1)?;
    (after == b']').then_some(([x, y, z], i + 1))
}

/// Reads the run of ASCII digits at `*i` onto `m` (`m · 10^k + digits`, wrapping), moving `*i`
/// past them; returns the new `m` and the number of digits. Eight bytes are looked at together
/// where the record has them: coordinates are mostly 6 to 9 digits.
#[inline]
fn digit_run(b: &[u8], i: &mut usize, mut m: u64) -> (u64, usize) {
    let start = *i;
    while let Some(chunk) = b.get(*i..*i + 8) {
        let word = u64::from_le_bytes(chunk.try_into().expect("eight bytes"));
        let x = word.wrapping_sub(0x3030_3030_3030_3030);
        // A byte's top bit is set where it is not a digit; carries only run from a lower byte
        // that is not a digit into higher ones, so the lowest flagged byte is exact.
        let not_digit = (x | x.wrapping_add(0x7676_7676_7676_7676)) & 0x8080_8080_8080_8080;
        let k = (not_digit.trailing_zeros() / 8) as usize;
        if k == 0 {
            break;
        }
        // The k digits, first one in the lowest byte, moved to the top so that the bytes below
        // them read as leading zeros.
        m = m
            .wrapping_mul(POW10_U64[k])
            .wrapping_add(eight_digits(x << (8 * (8 - k))));
        *i += k;
        if k < 8 {
            return (m, *i - start);
        }
    }
    while let Some(&c) = b.get(*i) {
        if !c.is_ascii_digit() {
            break;
        }
        m = m.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
        *i += 1;
    }
    (m, *i - start)
}

/// The eight digit values (0 to 9) in the bytes of `v`, the first in the lowest byte, as one
/// number.
#[inline]
fn eight_digits(mut v: u64) -> u64 {
    v = (v.wrapping_mul(10) + (v >> 8)) & 0x00FF_00FF_00FF_00FF;
    v = (v.wrapping_mul(100) + (v >> 16)) & 0x0000_FFFF_0000_FFFF;
    (v.wrapping_mul(10_000) + (v >> 32)) & 0xFFFF_FFFF
}

/// 10^k for the digit counts read at once.
const POW10_U64: [u64; 15] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
    10_000_000_000,
    100_000_000_000,
    1_000_000_000_000,
    10_000_000_000_000,
    100_000_000_000_000,
];

/// Sets `slot` once; a second value for the same field is left to serde_json, which refuses it.
#[inline]
fn once<T>(slot: &mut Option<T>, value: Option<T>) -> Option<()> {
    if slot.is_some() {
        return None;
    }
    *slot = Some(value?);
    Some(())
}

fn hit<'a>(c: &mut Cursor<'a>) -> Option<RawHit<'a>> {
    let (mut t, mut point, mut normal, mut entity) = (None, None, None, None);
    const ORDER: [Known; 4] = [
        Known::new(b"t"),
        Known::new(b"point"),
        Known::new(b"normal"),
        Known::new(b"entity"),
    ];
    // Each field by its place in `ORDER`.
    c.object(&ORDER, |c, k| match k {
        Some(0) => once(&mut t, c.nullable(Cursor::f64)),
        Some(1) => once(&mut point, c.nullable(Cursor::vec3)),
        Some(2) => once(&mut normal, c.nullable(Cursor::vec3)),
        Some(3) => once(&mut entity, c.nullable(|c| c.string().map(Cow::Borrowed))),
        _ => c.skip_value(0),
    })?;
    Some(RawHit {
        t: t.flatten(),
        point: point.flatten(),
        normal: normal.flatten(),
        entity: entity.flatten(),
    })
}

/// Reads one record of the common shape, or `None` to leave it to serde_json.
pub(super) fn parse(bytes: &[u8]) -> Option<RawRay<'_>> {
    let mut c = Cursor { b: bytes, i: 0 };
    let (mut pixel, mut sample, mut id, mut parent, mut kind) = (None, None, None, None, None);
    let (mut origin, mut direction, mut from, mut to) = (None, None, None, None);
    let (mut hit_, mut light, mut blocked_by, mut color) = (None, None, None, None);
    // The order rayscope's kits and its own logs write.
    const ORDER: [Known; 13] = [
        Known::new(b"pixel"),
        Known::new(b"sample"),
        Known::new(b"id"),
        Known::new(b"parent"),
        Known::new(b"kind"),
        Known::new(b"origin"),
        Known::new(b"direction"),
        Known::new(b"from"),
        Known::new(b"to"),
        Known::new(b"hit"),
        Known::new(b"light"),
        Known::new(b"blocked_by"),
        Known::new(b"color"),
    ];
    // Each field by its place in `ORDER`.
    c.object(&ORDER, |c, k| match k {
        Some(0) => once(&mut pixel, c.nullable(Cursor::pixel)),
        Some(1) => once(&mut sample, c.nullable(Cursor::u32)),
        Some(2) => once(&mut id, c.nullable(Cursor::i64)),
        Some(3) => once(&mut parent, c.nullable(Cursor::i64)),
        Some(4) => once(&mut kind, c.nullable(Cursor::word)),
        Some(5) => once(&mut origin, c.nullable(Cursor::vec3)),
        Some(6) => once(&mut direction, c.nullable(Cursor::vec3)),
        Some(7) => once(&mut from, c.nullable(Cursor::vec3)),
        Some(8) => once(&mut to, c.nullable(Cursor::vec3)),
        Some(9) => once(&mut hit_, c.nullable(hit)),
        Some(10) => once(
            &mut light,
            c.nullable(|c| c.string().map(|s| LightRef::Name(Cow::Borrowed(s)))),
        ),
        Some(11) => once(
            &mut blocked_by,
            c.nullable(|c| c.string().map(|s| BlockerRef::Name(Cow::Borrowed(s)))),
        ),
        Some(12) => once(&mut color, c.nullable(Cursor::vec3)),
        _ => c.skip_value(0),
    })?;
    c.skip_ws();
    if c.i != bytes.len() {
        return None;
    }
    Some(RawRay {
        pixel: pixel.flatten(),
        sample: sample.flatten(),
        id: id.flatten(),
        parent: parent.flatten(),
        kind: kind.flatten(),
        origin: origin.flatten(),
        direction: direction.flatten(),
        from: from.flatten(),
        to: to.flatten(),
        hit: hit_,
        light: light.flatten(),
        blocked_by,
        color: color.flatten(),
    })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn serde(line: &str) -> Option<RawRay<'_>> {
        serde_json::from_str(line).ok()
    }

    /// The fast reader either reads `line` exactly as serde_json does or leaves it to serde_json.
    fn agrees(line: &str) -> bool {
        match parse(line.as_bytes()) {
            Some(fast) => serde(line).as_ref() == Some(&fast),
            None => true,
        }
    }

    #[test]
    fn reads_the_records_tracers_write_as_serde_json_does() {
        let lines = [
            r#"{"pixel":[0,0],"sample":0,"id":0,"parent":null,"kind":"camera","origin":[0,0,0],"direction":[-0.44687796,0.44687796,0.774984],"hit":{"t":2.2377474,"point":[-1,1,1.7342185],"normal":[0,-1,0],"entity":"Roof"}}"#,
            r#"{"pixel":[3,1],"sample":2,"id":1,"parent":0,"kind":"shadow","origin":[-1,0.99998266,1.7342185],"direction":[0.9557018,-0.19112378,-0.22384304],"light":"Light1","blocked_by":null}"#,
            r#"{"pixel":[3,1],"id":7,"parent":3,"kind":"shadow","from":[1e-3,2E+2,-0.5e-7],"to":[4,5,6],"light":"L","blocked_by":"Box"}"#,
            r#" { "pixel" : [ 10 , 20 ] , "kind" : "reflection" , "origin" : [ 1.5 , -2 , 3 ] , "direction" : [ 0 , 0 , 1 ] , "hit" : null } "#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{}}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{"t":null,"entity":null}}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"depth":3,"colour":[0.5,0.25,1],"debug":{"a":[1,{"b":null}],"c":true,"d":false,"e":"x"}}"#,
            r#"{"origin":[-0,0.0,-0.0],"direction":[123456789012345678901234567890,1e-310,-1.7976931348623157e308]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"id":-5,"parent":9223372036854775807}"#,
            "{\"origin\":[0,0,0],\"direction\":[0,0,1],\"kind\":\"ré\u{fb01}exion\"}",
        ];
        for line in lines {
            let fast = parse(line.as_bytes()).unwrap_or_else(|| panic!("the fast reader refused {line}"));
            assert_eq!(Some(fast), serde(line), "{line}");
        }
    }

    #[test]
    fn reads_decimals_bit_exactly_on_both_sides_of_the_short_path_limits() {
        let numbers = [
            "0.1",
            "-0.30000000000000004",
            "-0",
            "-0.0",
            "9007199254740992",
            "9007199254740993",
            "-900719925474099.3",
            "0.9007199254740993",
            "1234567890123456789",
            "12345678901234567890",
            "0.0000000000000000000001",
            "0.00000000000000000000001",
            "1.000000000000000000001",
            "0.000000000000000000000000000000000000000000001401298",
            "179769313486231570000000000000000000000000000000000000000000000",
            "3.4028235e38",
            "0.44704583",
        ];
        for n in numbers {
            let line = format!(r#"{{"origin":[{n},0,0],"direction":[0,0,1]}}"#);
            let fast = parse(line.as_bytes()).unwrap_or_else(|| panic!("the fast reader refused {n}"));
            let want: f64 = n.parse().expect("a number");
            assert_eq!(fast.origin.map(|o| o[0].to_bits()), Some(want.to_bits()), "{n}");
            let slow = serde(&line).expect("serde_json reads it");
            assert_eq!(slow.origin.map(|o| o[0].to_bits()), Some(want.to_bits()), "{n}");
        }
    }

    #[test]
    fn leaves_what_it_cannot_read_exactly_to_serde_json() {
        let lines = [
            // Escapes, duplicate fields, trailing text, wrong shapes, JSON's number grammar.
            r#"{"origin":[0,0,0],"direction":[0,0,1],"kind":"cam\"era"}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"kind":"a\u0041"}"#,
            r#"{"origin":[0,0,0],"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1]} x"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],}"#,
            r#"{"origin":[0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[0,0,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[01,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[1.,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[.5,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[+1,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[NaN,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[1e999,0,0],"direction":[0,0,1]}"#,
            r#"{"pixel":[1.0,2],"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"pixel":[-1,2],"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"sample":4294967296,"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"id":1e2,"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{"t":1,"t":2}}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":[1]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{"t":1}"#,
            "{\"origin\":[0,0,0],\"direction\":[0,0,1],\"kind\":\"a\tb\"}",
            r#"[1,2,3]"#,
            r#"{"origin":[0,0,0] "direction":[0,0,1]}"#,
        ];
        for line in lines {
            assert!(parse(line.as_bytes()).is_none(), "the fast reader accepted {line}");
        }
        // And a string that is not UTF-8.
        assert!(parse(b"{\"origin\":[0,0,0],\"direction\":[0,0,1],\"kind\":\"\xff\"}").is_none());
    }

    /// A number written in one of the ways tracers print floats.
    fn number() -> impl Strategy<Value = String> {
        prop_oneof![
            any::<f32>()
                .prop_filter("finite", |v| v.is_finite())
                .prop_map(|v| format!("{v}")),
            any::<f64>()
                .prop_filter("finite", |v| v.is_finite())
                .prop_map(|v| format!("{v:e}")),
            (-1e6f64..1e6).prop_map(|v| format!("{v:.9}")),
            (-1000i64..1000).prop_map(|v| v.to_string()),
            (-1e6f64..1e6).prop_map(|v| format!("{v:E}")),
        ]
    }

    fn vec3() -> impl Strategy<Value = String> {
        (number(), number(), number(), " ?", " ?").prop_map(|(x, y, z, a, b)| format!("[{x},{a}{y},{b}{z}]"))
    }

    fn member() -> impl Strategy<Value = String> {
        prop_oneof![
            (0u32..5000, 0u32..5000).prop_map(|(x, y)| format!("\"pixel\":[{x},{y}]")),
            (0u32..64).prop_map(|s| format!("\"sample\":{s}")),
            any::<i64>().prop_map(|v| format!("\"id\":{v}")),
            prop_oneof![Just("null".to_string()), any::<i32>().prop_map(|v| v.to_string())]
                .prop_map(|v| format!("\"parent\":{v}")),
            "[a-z]{1,10}".prop_map(|k| format!("\"kind\":\"{k}\"")),
            vec3().prop_map(|v| format!("\"origin\":{v}")),
            vec3().prop_map(|v| format!("\"direction\":{v}")),
            vec3().prop_map(|v| format!("\"to\":{v}")),
            vec3().prop_map(|v| format!("\"color\":{v}")),
            (number(), vec3(), "[A-Za-z0-9 ]{0,12}")
                .prop_map(|(t, n, e)| format!("\"hit\":{{\"t\":{t},\"normal\":{n},\"entity\":\"{e}\"}}")),
            Just("\"hit\":null".to_string()),
            "[A-Za-z0-9]{1,8}".prop_map(|l| format!("\"light\":\"{l}\"")),
            prop_oneof![
                Just("null".to_string()),
                "[A-Za-z]{1,8}".prop_map(|b| format!("\"{b}\""))
            ]
            .prop_map(|b| format!("\"blocked_by\":{b}")),
            (number(), "[a-z]{1,6}").prop_map(|(v, k)| format!("\"x_{k}\":[{v},{{\"q\":[true,null]}}]")),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        #[test]
        fn random_records_read_as_serde_json_reads_them(
            members in proptest::collection::vec(member(), 0..10),
            spaced in any::<bool>(),
        ) {
            let sep = if spaced { ", " } else { "," };
            let line = format!("{{{}}}", members.join(sep));
            prop_assert!(agrees(&line), "{line}");
            // Records without a repeated field are read by the fast reader itself.
            let mut keys: Vec<&str> = members.iter().map(|m| m.split(':').next().unwrap_or("")).collect();
            keys.sort_unstable();
            let distinct = keys.windows(2).all(|w| w[0] != w[1]);
            if distinct {
                prop_assert!(parse(line.as_bytes()).is_some(), "refused {line}");
            }
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// The eight-at-a-time digit reader reads what a digit-by-digit loop reads, whatever
        /// surrounds the digits (borrows and carries between bytes included).
        #[test]
        fn digit_runs_read_as_one_digit_at_a_time(bytes in proptest::collection::vec(
            prop_oneof![4 => b'0'..=b'9', 1 => any::<u8>()], 0..40), start in 0usize..40, m0 in 0u64..1_000_000) {
            let start = start.min(bytes.len());
            let mut i = start;
            let got = digit_run(&bytes, &mut i, m0);
            let (mut m, mut j) = (m0, start);
            while j < bytes.len() && bytes[j].is_ascii_digit() {
                m = m.wrapping_mul(10).wrapping_add(u64::from(bytes[j] - b'0'));
                j += 1;
            }
            prop_assert_eq!(got, (m, j - start));
            prop_assert_eq!(i, j);
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6000))]
        /// Triples read with their separators found first give what reading one number after
        /// the other gives, for triples of any length (up to 52 bytes of decimals that the
        /// short path reads), wrong separators and text cut short included.
        #[test]
        fn triples_read_side_by_side_as_one_after_the_other(
            parts in proptest::collection::vec(prop_oneof![
                4 => "-?(0|[1-9][0-9]{0,6})(\\.[0-9]{1,14})?",
                1 => prop_oneof![Just(","), Just("]"), Just("["), Just(" "), Just("e5"), Just("")].prop_map(str::to_string),
            ], 0..6),
            seps in proptest::collection::vec(prop_oneof![8 => Just(","), 2 => Just("]"), 1 => Just(",,"), 1 => Just("")], 3),
            cut in 0usize..70,
        ) {
            let mut text = String::from("[");
            for (k, p) in parts.iter().take(3).enumerate() {
                text.push_str(p);
                text.push_str(seps[k]);
            }
            text.push('}');
            let text = &text[..text.len().min(cut.max(1))];
            let b = text.as_bytes();
            prop_assert_eq!(tight_vec3(b, 0), tight_vec3_serial(b, 0), "{}", text);
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6000))]
        /// The shortest decimals of f32 and f64 values (as tracers print them), as bracketed
        /// triples without spaces, at the end of a record or before more of it, are read bit
        /// for bit as the standard library reads them.
        #[test]
        fn printed_floats_in_triples_read_as_the_standard_library_reads_them(
            v in proptest::array::uniform3(prop_oneof![
                any::<f32>().prop_filter("finite", |v| v.is_finite()).prop_map(|v| format!("{v}")),
                any::<f64>().prop_filter("finite", |v| v.is_finite()).prop_map(|v| format!("{v}")),
                (-1e3f32..1e3).prop_map(|v| format!("{v}")),
                (-1f32..1.0).prop_map(|v| format!("{v}")),
            ]),
            tail in prop_oneof![Just(String::new()), Just("}".to_string()), Just(",\"color\":[0,0,0]}".to_string())],
        ) {
            let text = format!("[{},{},{}]{tail}", v[0], v[1], v[2]);
            let want: Vec<u64> = v.iter().map(|x| x.parse::<f64>().expect("a number").to_bits()).collect();
            let mut c = Cursor { b: text.as_bytes(), i: 0 };
            let general = c.vec3().map(|a| a.map(f64::to_bits).to_vec());
            prop_assert_eq!(general.as_ref(), Some(&want), "{}", text);
            let end = text.len() - tail.len();
            prop_assert_eq!(c.i, end, "{}", text);
            if let Some((got, at)) = tight_vec3(text.as_bytes(), 0) {
                prop_assert_eq!(got.map(f64::to_bits).to_vec(), want, "{}", text);
                prop_assert_eq!(at, end, "{}", text);
            }
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Decimals, read sixteen bytes at a time where they fit, are read bit for bit as the
        /// standard library reads them, and the cursor stops where JSON's grammar ends them.
        #[test]
        fn decimals_read_as_the_standard_library_reads_them(
            negative in any::<bool>(),
            int in "0|[1-9][0-9]{0,8}",
            frac in proptest::option::of(prop_oneof!["[0-9]{1,16}", "0{1,12}[1-9][0-9]{0,8}"]),
            after in prop_oneof![Just(",".to_string()), Just("]".to_string()), Just("e5".to_string()),
                Just(".".to_string()), "[ -~]{0,20}"],
        ) {
            let number = format!("{}{int}{}", if negative { "-" } else { "" },
                frac.as_ref().map_or(String::new(), |f| format!(".{f}")));
            let text = format!("{number}{after}");
            let mut c = Cursor { b: text.as_bytes(), i: 0 };
            let got = c.f64();
            // Where the text after it would continue the number (an exponent, a point, a digit),
            // the number read is another one: those are the other tests' business.
            let continues = after.starts_with(|ch: char| matches!(ch, 'e' | 'E' | '.' | '0'..='9'));
            if !continues || (after.starts_with('.') && frac.is_some()) {
                let want: f64 = number.parse().expect("a number");
                prop_assert_eq!(got.map(f64::to_bits), Some(want.to_bits()), "{}", text);
                prop_assert_eq!(c.i, number.len(), "{}", text);
            }
        }
    }
    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Strings are read sixteen bytes at a time as they are one byte at a time: the same end,
        /// the same refusals (escapes, control characters) and the same ASCII answer.
        #[test]
        fn strings_read_as_one_byte_at_a_time(body in proptest::collection::vec(
            prop_oneof![6 => b'a'..=b'z', 1 => Just(b'"'), 1 => Just(b'\\'), 1 => any::<u8>()], 0..40)) {
            let mut line = vec![b'"'];
            line.extend(&body);
            let mut c = Cursor { b: &line, i: 0 };
            let got = c.string_bytes().map(|(s, ascii)| (s.to_vec(), ascii, c.i));
            let want = body.iter().position(|&x| x == b'"' || x == b'\\' || x < 0x20).and_then(|n| {
                (body[n] == b'"').then(|| (body[..n].to_vec(), body[..n].is_ascii(), n + 2))
            });
            prop_assert_eq!(got, want);
        }
    }
}
