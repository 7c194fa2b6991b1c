//! A force packet from the network: decoded or refused, never a panic; what decodes is finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_io::force::{plausible, ForceLayout};

fuzz_target!(|data: &[u8]| {
    // The first byte picks a layout, the rest is the datagram.
    let layouts = [
        "counter,fx,fy,fz,tx,ty,tz",
        "timestamp_s,fx,fy,fz",
        "counter,fz",
        "timestamp_s,fz,tz",
    ];
    let Some((&pick, packet)) = data.split_first() else {
        return;
    };
    let layout = ForceLayout::parse(layouts[usize::from(pick) % layouts.len()]).unwrap();
    if let Ok(s) = layout.decode(packet) {
        assert!(s.timestamp_s.is_finite());
        assert!(s.values.iter().all(|v| v.is_finite()));
        let _ = plausible(&s);
    }
    // The layout parser itself takes text from the command line.
    if let Ok(text) = std::str::from_utf8(packet) {
        if let Ok(l) = ForceLayout::parse(text) {
            assert!(l.packet_len() > 0);
        }
    }
});
