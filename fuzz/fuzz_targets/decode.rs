//! Any bytes through every decoder: no panic, and whatever decodes
//! re-encodes to a fixed point (encode ∘ decode ∘ encode = encode).
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::frame::read_frame;
use protocol::{decode_reply, decode_request, encode_reply, encode_request, ImageEncoding};

fuzz_target!(|data: &[u8]| {
    let mut body = Vec::new();
    let _ = read_frame(&mut &data[..], &mut body, 1 << 16);

    if let Ok(req) = decode_request(data) {
        let mut a = Vec::new();
        encode_request(&req, &mut a);
        let again = decode_request(&a).expect("our own encoding decodes");
        let mut b = Vec::new();
        encode_request(&again, &mut b);
        assert_eq!(a, b);
    }
    if let Ok(rep) = decode_reply(data) {
        for enc in [ImageEncoding::Array, ImageEncoding::Base64] {
            let mut a = Vec::new();
            encode_reply(&rep, enc, &mut a);
            let again = decode_reply(&a).expect("our own encoding decodes");
            let mut b = Vec::new();
            encode_reply(&again, enc, &mut b);
            assert_eq!(a, b);
        }
    }
});
