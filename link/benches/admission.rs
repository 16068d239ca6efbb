//! What a received frame costs the link, one thread: `cargo bench -p deckwatch-link --bench
//! admission`. A signed autopilot attitude admitted (checksum, signature, replay check, parse);
//! the same frame unsigned with signing required (refused after the checksum); a frame signed
//! with another key (refused after the signature); and one beyond its sender's rate (refused
//! before anything else): the cost of each kind of flood per frame.

use criterion::Criterion;
use deckwatch_link::admission::{frame, Admission, Refusal};
use deckwatch_link::dialect::ATTITUDE_QUATERNION_DATA;
use deckwatch_link::signing::Signing;
use deckwatch_link::{LinkConfig, MavHeader, MavMessage, SigningMode};
use std::hint::black_box;
use std::net::SocketAddr;
use std::sync::Arc;

fn main() {
    let mut c = Criterion::default().sample_size(50).configure_from_args();
    let mut group = c.benchmark_group("admission");
    let key = [3u8; 32];
    let config = LinkConfig {
        signing: SigningMode::Required,
        signing_key_file: "unused".into(),
        sender_rate_hz: 100_000.0,
        ..LinkConfig::default()
    };
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    let attitude = MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
        time_boot_ms: 1,
        q1: 1.0,
        ..Default::default()
    });
    let from: SocketAddr = ([127, 0, 0, 1], 14550).into();
    let autopilot = Signing::new(key, 1);
    let mut admission = Admission::new(&config, Some(Arc::new(Signing::new(key, 0))));
    // What is measured is what it says: admitted, and refused for its cause.
    assert_eq!(
        admission
            .datagram(&frame(header, &attitude, Some(&autopilot)), from, 0)
            .len(),
        1
    );
    // The clock moves 1 ms a frame: the sender stays within its rate.
    let mut now_ns = 0u64;
    let mut tick = || {
        now_ns += 1_000_000;
        now_ns
    };
    // A fresh signature per frame (a replayed one is refused, which is another case).
    group.bench_function("signed_admitted", |b| {
        b.iter_batched(
            || frame(header, &attitude, Some(&autopilot)),
            |f| black_box(admission.datagram(&f, from, tick()).len()),
            criterion::BatchSize::SmallInput,
        )
    });
    let unsigned = frame(header, &attitude, None);
    group.bench_function("unsigned_refused", |b| {
        b.iter(|| black_box(admission.datagram(&unsigned, from, tick()).len()))
    });
    let other_key = frame(header, &attitude, Some(&Signing::new([9; 32], 2)));
    group.bench_function("bad_signature_refused", |b| {
        b.iter(|| black_box(admission.datagram(&other_key, from, tick()).len()))
    });
    let limited = LinkConfig {
        sender_rate_hz: 100.0,
        ..config.clone()
    };
    let mut limiter = Admission::new(&limited, Some(Arc::new(Signing::new(key, 0))));
    // Its burst spent at time 0: every frame after is over the rate.
    for _ in 0..100 {
        limiter.datagram(&other_key, from, 0);
    }
    // Every fresh signed frame was admitted (none refused as a replay); the others refused for
    // their own causes.
    assert!(
        admission.admitted > 1
            && admission.refused.get(Refusal::Replay) == 0
            && admission.refused.get(Refusal::RateLimited) == 0
    );
    assert!(
        admission.refused.get(Refusal::Unsigned) > 0 && admission.refused.get(Refusal::BadSignature) > 0,
        "{}",
        admission.refused.describe()
    );
    group.bench_function("rate_limited", |b| {
        b.iter(|| black_box(limiter.datagram(&other_key, from, 0).len()))
    });
    group.finish();
    c.final_summary();
}
