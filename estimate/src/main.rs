//! `deckwatch-estimate`: the estimate stage. Sleeps until detect publishes markers, estimates the
//! deck attitude of each marker set, publishes it to decide. Runs until SIGINT/SIGTERM.

use clap::Parser;
use deckwatch_common::bus::{event_loop, quiet_logging, Bus, BusError, Flow, StageArgs};
use deckwatch_common::messages::{monotonic_ns, AttitudeMessage, MarkerMessage};
use deckwatch_common::scene::{SceneGeometry, Viewpoint};
use deckwatch_estimate::stage::{EstimateConfig, EstimateStage};
use deckwatch_viz::{Item, ItemKind, Logger, RerunConfig};
use std::process::ExitCode;

#[derive(Parser)]
#[command(version, about = "deckwatch estimate stage: deck attitude from markers")]
struct Args {
    #[command(flatten)]
    stage: StageArgs,
}

fn run(a: Args) -> Result<(), String> {
    let (file, text) = a.stage.read_config()?;
    let bus_config = a.stage.bus_config(&file, &text)?;
    let mut stage = EstimateStage::new(&EstimateConfig::from_toml(&file, &text)?, a.stage.restarted)?;
    let logger = Logger::start(&RerunConfig::from_toml(&file, &text)?, "estimate")?;
    quiet_logging();
    let bus = Bus::join(&bus_config.settings(1), "estimate").map_err(|e| e.to_string())?;
    let input = bus.subscriber::<MarkerMessage>().map_err(|e| e.to_string())?;
    let output = bus.publisher::<AttitudeMessage>().map_err(|e| e.to_string())?;
    event_loop(&[input.listener()], None, |_| {
        while let Some(m) = input.receive()? {
            let attitude = stage.process(&m, monotonic_ns());
            output.send(&attitude)?;
            if let Some(l) = &logger {
                for item in viewer_items(&attitude) {
                    l.log(item);
                }
            }
        }
        Ok::<Flow, BusError>(Flow::Continue)
    })
    .map_err(|e| e.to_string())?;
    eprintln!(
        "deckwatch-estimate: {} marker sets, {} attitudes, {} dropped",
        stage.processed, stage.estimated, stage.dropped
    );
    Ok(())
}

/// Angles, the paper's ellipse and the deck reprojected with the full pose, for the viewer.
fn viewer_items(a: &AttitudeMessage) -> Vec<Item> {
    let (seq, captured_ns) = (a.stamp.seq, a.stamp.times.captured_ns);
    let item = |kind| Item {
        seq,
        captured_ns,
        kind,
    };
    let mut out = Vec::with_capacity(4);
    let mut scalars = Vec::new();
    if a.valid {
        for (name, v) in ["roll", "pitch", "yaw"].iter().zip(a.rpy.to_degrees()) {
            scalars.push((format!("attitude/{name}/{}", a.estimator.name()), v));
        }
    }
    if a.alternative.present && a.alternative.valid {
        for (name, v) in ["roll", "pitch", "yaw"]
            .iter()
            .zip(a.alternative.rpy.to_degrees())
        {
            scalars.push((format!("attitude/{name}/{}", a.alternative.estimator.name()), v));
        }
    }
    out.push(item(ItemKind::Scalars(scalars)));
    let camera = &a.context.camera;
    if a.has_image_ellipse {
        let strip = a
            .image_ellipse
            .boundary(64)
            .iter()
            .map(|&p| camera.distort_pixel(p))
            .map(|[u, v]| [u as f32, v as f32])
            .collect();
        out.push(item(ItemKind::Strips {
            entity: "camera/image/ellipse",
            strips: vec![strip],
        }));
    }
    let [x, y, z] = a.camera_position_m;
    if a.valid && z.is_finite() {
        let scene = SceneGeometry {
            attitude: a.rpy.to_matrix(),
            viewpoint: Viewpoint {
                offset_x_m: x,
                offset_y_m: y,
                altitude_m: z,
            },
        };
        let deck = &a.context.deck;
        let points: Vec<[f32; 2]> = scene
            .project_markers(camera, deck)
            .into_iter()
            .flatten()
            .map(|[u, v]| [u as f32, v as f32])
            .collect();
        let ring: Vec<[f32; 2]> = (0..=64)
            .filter_map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 64.0;
                let p =
                    nalgebra::Vector3::new(deck.ring_radius_m * t.cos(), deck.ring_radius_m * t.sin(), 0.0);
                scene
                    .project_deck_point(camera, &p)
                    .map(|[u, v]| [u as f32, v as f32])
            })
            .collect();
        let labels = vec![String::new(); points.len()];
        out.push(item(ItemKind::Points {
            entity: "camera/image/deck_model",
            points,
            labels,
        }));
        out.push(item(ItemKind::Strips {
            entity: "camera/image/deck_model/ring",
            strips: vec![ring],
        }));
    }
    out
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("deckwatch-estimate: {e}");
            ExitCode::FAILURE
        }
    }
}
