//! Part file bytes → `rayscope merge`'s header reader. Never panics, never allocates for sizes it
//! has not checked, and accepts only headers within the limits.
//!
//! Input that starts with OpenEXR's magic number is a whole part file (EXR header with the JSON
//! in it); anything else is the JSON alone, checked as the merge checks it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rayscope_core::farm::{read_part_header, PartHeader, MAX_HEADER_BYTES};
use rayscope_core::settings::{Limits, Ranges};

/// The command line's limits without `--allow-large`, without asking the system for its memory.
const LIMITS: Limits = Limits {
    ranges: Ranges::COMMAND_LINE,
    max_pixels: 8192 * 8192,
    memory_bytes: 2 << 30,
    max_grid_samples: Some(16 * 8192 * 8192),
    max_samples: None,
    pixel_hint: "",
    memory_hint: "",
};

fuzz_target!(|data: &[u8]| {
    if data.len() as u64 > 2 * MAX_HEADER_BYTES {
        return;
    }
    let header = if data.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        read_part_header(data, data.len() as u64, &LIMITS)
    } else {
        let Ok(text) = std::str::from_utf8(data) else {
            return;
        };
        PartHeader::from_json(text)
    };
    match header {
        Ok(h) => {
            if let Ok((w, ht)) = h.check(&LIMITS) {
                assert!(u64::from(w) * u64::from(ht) <= LIMITS.max_pixels);
                assert!(h.part < h.parts);
                let tiles = u64::from(w.div_ceil(16)) * u64::from(ht.div_ceil(16));
                assert!(u64::from(h.parts) <= tiles);
            }
        }
        Err(e) => assert!(!e.is_empty()),
    }
});
