//! A line a probed program answers with → `rayscope_check::probe_answer::parse_answer`. Never
//! panics; an error answer's message and the reason a line is refused stay short; a hit has a
//! `t` or a point.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rayscope_check::probe_answer::{parse_answer, Answer, MAX_ERROR_MESSAGE};

fuzz_target!(|data: &[u8]| {
    let line = String::from_utf8_lossy(data);
    // Read as the answer to requests 0 to 3, so that a seed's id matches once.
    for id in 0..4 {
        match parse_answer(&line, id) {
            Ok(Answer::Error(message)) => assert!(message.len() <= MAX_ERROR_MESSAGE + " …".len()),
            Ok(Answer::Hit { t, point, .. }) => assert!(t.is_some() || point.is_some()),
            Ok(Answer::Miss) => {}
            Err(why) => assert!(!why.is_empty() && why.len() < 1024, "{why}"),
        }
    }
});
