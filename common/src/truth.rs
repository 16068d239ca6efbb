//! What a simulated (or surveyed) frame knows of the truth: the deck's and the vehicle's
//! attitude, heights and rates, each optional. Recordings carry it as optional columns of
//! `frames.csv` (the `deckwatch-formats` crate), frames carry it as `messages::Truth`.

use crate::rotation::Rpy;

/// Ground truth and altimeter columns of one frame; None where the column is absent or the value
/// is unknown (`nan`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroundTruth {
    pub roll_deg: Option<f64>,
    pub pitch_deg: Option<f64>,
    pub yaw_deg: Option<f64>,
    pub alt_m: Option<f64>,
    pub offset_x_m: Option<f64>,
    pub offset_y_m: Option<f64>,
    /// The attitude of the vehicle carrying the camera at mid-exposure (`R_V`, body to world,
    /// X-Y-Z degrees; CONVENTIONS.md §5); None: a level camera.
    pub vehicle_roll_deg: Option<f64>,
    pub vehicle_pitch_deg: Option<f64>,
    pub vehicle_yaw_deg: Option<f64>,
    /// The vehicle's height in W (m, z up; the simulator's origin is the deck centre's mean):
    /// with the full pose it gives the deck's heave.
    pub vehicle_height_m: Option<f64>,
    /// The deck centre's true height in W (m): the heave.
    pub deck_heave_m: Option<f64>,
    /// The vehicle's angular velocity in W at mid-exposure (deg/s; what a gyro gives): a
    /// rolling shutter's rows see the camera turned by it.
    pub vehicle_rate_x_dps: Option<f64>,
    pub vehicle_rate_y_dps: Option<f64>,
    pub vehicle_rate_z_dps: Option<f64>,
}

impl GroundTruth {
    /// The true attitude, when all three angles are known.
    pub fn attitude(&self) -> Option<Rpy> {
        Some(Rpy::from_degrees(self.roll_deg?, self.pitch_deg?, self.yaw_deg?))
    }

    /// The vehicle's attitude, when all three of its angles are known.
    pub fn vehicle_attitude(&self) -> Option<Rpy> {
        Some(Rpy::from_degrees(
            self.vehicle_roll_deg?,
            self.vehicle_pitch_deg?,
            self.vehicle_yaw_deg?,
        ))
    }

    /// The vehicle's angular velocity in W (deg/s), when all three components are known.
    pub fn vehicle_rate_dps(&self) -> Option<[f64; 3]> {
        Some([
            self.vehicle_rate_x_dps?,
            self.vehicle_rate_y_dps?,
            self.vehicle_rate_z_dps?,
        ])
    }

    /// The values in [`TRUTH_COLUMNS`] order.
    pub fn values(&self) -> [Option<f64>; TRUTH_COLUMNS.len()] {
        [
            self.roll_deg,
            self.pitch_deg,
            self.yaw_deg,
            self.alt_m,
            self.offset_x_m,
            self.offset_y_m,
            self.vehicle_roll_deg,
            self.vehicle_pitch_deg,
            self.vehicle_yaw_deg,
            self.vehicle_height_m,
            self.deck_heave_m,
            self.vehicle_rate_x_dps,
            self.vehicle_rate_y_dps,
            self.vehicle_rate_z_dps,
        ]
    }

    /// Sets the value of column `column` of [`TRUTH_COLUMNS`].
    pub fn set(&mut self, column: usize, v: Option<f64>) {
        match column {
            0 => self.roll_deg = v,
            1 => self.pitch_deg = v,
            2 => self.yaw_deg = v,
            3 => self.alt_m = v,
            4 => self.offset_x_m = v,
            5 => self.offset_y_m = v,
            6 => self.vehicle_roll_deg = v,
            7 => self.vehicle_pitch_deg = v,
            8 => self.vehicle_yaw_deg = v,
            9 => self.vehicle_height_m = v,
            10 => self.deck_heave_m = v,
            11 => self.vehicle_rate_x_dps = v,
            12 => self.vehicle_rate_y_dps = v,
            _ => self.vehicle_rate_z_dps = v,
        }
    }
}

/// Names of the optional ground-truth columns, in [`GroundTruth`] order.
pub const TRUTH_COLUMNS: [&str; 14] = [
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "alt_m",
    "offset_x_m",
    "offset_y_m",
    "vehicle_roll_deg",
    "vehicle_pitch_deg",
    "vehicle_yaw_deg",
    "vehicle_height_m",
    "deck_heave_m",
    "vehicle_rate_x_dps",
    "vehicle_rate_y_dps",
    "vehicle_rate_z_dps",
];

/// Which columns of [`TRUTH_COLUMNS`] a recording has or a writer writes.
pub type TruthColumns = [bool; TRUTH_COLUMNS.len()];

/// Every ground-truth column but the vehicle's (a level camera) and the heave's.
pub const LEVEL_TRUTH: TruthColumns = [
    true, true, true, true, true, true, false, false, false, false, false, false, false, false,
];
/// The vehicle's height in W and the deck's heave (columns 9 and 10), added to a set.
pub const fn with_heave_truth(mut columns: TruthColumns) -> TruthColumns {
    columns[9] = true;
    columns[10] = true;
    columns
}
/// Every ground-truth column.
pub const ALL_TRUTH: TruthColumns = [true; TRUTH_COLUMNS.len()];
/// No ground-truth column (a real camera).
pub const NO_TRUTH: TruthColumns = [false; TRUTH_COLUMNS.len()];
