//! Every message, and every part of one, with all of its fields: listed once.

/// Hands every message type and part, each with all of its fields, to the macro `$callback`,
/// one `$callback!(Type { field, ... })` per type. After a `;` come fields added after
/// recordings were made, with the value an older recording implies (`readout_s = 0.0`).
///
/// The wire check of every message (this crate, [`crate::wire_check_struct`]) and a flight
/// recording's JSON (`deckwatch-flight`) are generated from this one list. Both take each
/// struct apart or build it whole, so a field missing here is a compile error in both.
/// (`StageLog`, `LinkTraffic` and `StageHeartbeat` are not here: their recording is of their
/// own, a Foxglove log, hex bytes, nothing; their wire checks list their fields the same way.
/// Nor are `StageTimes` and `DropCounts`: a value per stage, whose names in a recording are
/// spelled from the stage table, `NAMES`.)
#[macro_export]
macro_rules! message_fields {
    ($callback:ident) => {
        $callback!(Rpy { roll, pitch, yaw });
        $callback!(Quaternion { w, x, y, z });
        $callback!(Euler313 { alpha, beta, gamma });
        $callback!(Ellipse {
            centre,
            semi_major,
            semi_minor,
            angle
        });
        $callback!(Distortion { k1, k2, p1, p2, k3 });
        $callback!(CameraModel {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion;
            readout_s = 0.0
        });
        $callback!(DeckLayout {
            ring_radius_m,
            marker_radius_m,
            bow_marker_radius_m,
            n_ring
        });
        $callback!(FrameStamp { seq, times, drops });
        $callback!(Truth {
            known,
            roll_deg,
            pitch_deg,
            yaw_deg,
            altitude_m,
            offset_x_m,
            offset_y_m,
            deck_heave_m,
        });
        $callback!(VehicleAttitude {
            compensation,
            rpy,
            age_ms,
            height_m;
            rate_dps = [f64::NAN; 3],
            acceleration_dps2 = [f64::NAN; 3]
        });
        $callback!(FrameContext {
            source,
            source_index,
            source_timestamp_ns,
            altitude_m,
            camera,
            deck,
            truth,
            vehicle,
        });
        $callback!(FrameHeader {
            stamp,
            context,
            width,
            height,
            stride,
            pixel_format
        });
        $callback!(Marker {
            valid,
            u,
            v,
            area_px,
            mean_intensity,
            quality;
            centre_std_px = f64::NAN
        });
        $callback!(RejectCounts {
            area,
            shape,
            border,
            unassigned
        });
        $callback!(MarkerSet {
            status,
            count,
            tracked,
            perspective_corrected,
            markers,
            rejected;
            out_of_view = 0
        });
        $callback!(MarkerMessage {
            stamp,
            context,
            markers
        });
        $callback!(AlternativeAttitude {
            present,
            estimator,
            valid,
            rpy
        });
        $callback!(AttitudeMessage {
            stamp,
            context,
            estimator,
            valid,
            failure,
            rpy,
            quaternion,
            euler313,
            has_image_ellipse,
            image_ellipse,
            residual,
            markers_used,
            rpy_std_deg,
            camera_position_m,
            alternative,
            vehicle,
            camera_rpy,
            deck_height_m;
            camera_position_covariance_m2 = [[f64::NAN; 3]; 3]
        });
        $callback!(LandingDecision {
            stamp,
            context,
            attitude,
            state,
            reason,
            calm_window_start_s,
            calm_window_length_s,
            heave_rate_mps,
            watchdog,
        });
        $callback!(VehicleSample {
            seq,
            time_ns,
            autopilot_time_us,
            received_ns,
            quaternion,
            altitude_m,
            height_m,
            vertical_speed_mps,
            clock_offset_ns,
            clock_method,
            clock_drift_ppm,
            link_up,
        });
    };
}
