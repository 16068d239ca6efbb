//! What every part of deckwatch shares, defined once: the frame and angle conventions, the camera
//! and deck models, image views, the messages and the ground truth. (The file formats are the
//! `deckwatch-formats` crate.)
//!
//! Conventions (CONVENTIONS.md): world frame W at the deck centre, x = bow of the level deck, y = port,
//! z = up; `P_world = R * P_deck`; `R = Rz(alpha) Rx(beta) Rz(gamma) = Rx(roll) Ry(pitch) Rz(yaw)`;
//! level camera looking down, image up = bow, image left = port; pixel centres at integers.

pub mod camera;
pub mod deck;
pub mod diag;
pub mod ellipse;
pub mod error;
pub mod files;
pub mod homography;
pub mod image;
#[cfg(feature = "jpeg")]
pub mod jpeg;
pub mod markers;
pub mod messages;
pub mod names;
pub mod rotation;
pub mod scene;
pub mod stats;
pub mod truth;
pub mod vehicle;
pub mod wire;

pub use camera::{CameraModel, Distortion};
pub use deck::DeckLayout;
pub use error::{InvalidField, InvalidOption};
pub use image::{GrayImage, GrayView, GrayViewMut};
pub use markers::{DetectionStatus, Marker, MarkerSet};
pub use rotation::{Attitude, Euler313, Quaternion, RotationMatrix, Rpy};
pub use scene::{SceneGeometry, Viewpoint};
pub use truth::GroundTruth;
pub use wire::{BadWireValue, WireBool, WireCheck, WireCode, WireEnum};
