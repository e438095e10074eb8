//! `synth-sequence`'s mover flags: objects as real footage has them (articulated, deforming,
//! stopping and starting, casting shadows), all off unless given.

use crate::cli::values;
use crate::commands::CommandError;
use crate::synth::{Body, Mover};

/// The mover flags of `synth-sequence`.
#[derive(Debug, Clone, PartialEq, Default, clap::Args)]
#[command(next_help_heading = "Movers (each off unless its flag is given; they need --objects)")]
pub struct MoverOptions {
    /// what each object is: block (a rigid textured rectangle), walker (a figure seen from the
    /// side, as tall as the object and 0.4 times as wide: head and torso gliding, arms and
    /// legs swinging, a stride every 16 to 32 frames) or blob (an ellipse stretching along one
    /// axis as it squashes along the other, by 20-35% every 12 to 30 frames) [default: block]
    #[arg(long, value_name = "KIND", value_parser = body)]
    pub object_kind: Option<Body>,
    /// the objects stop and start: each goes for 12 to 40 frames, stands for 8 to 24, and
    /// again (a walker's limbs stand with it)
    #[arg(long)]
    pub stop_go: bool,
    /// each object casts a shadow on the ground: its silhouette shifted by 0.3 to 0.5 times
    /// its height, the ground there at 45 to 65% of its brightness (not in objects.csv)
    #[arg(long)]
    pub shadows: bool,
    /// the objects' pace along their paths, 0.05 to 4 times the usual one (which reaches
    /// several px a frame; 0.1 to 0.2 for distant walkers), strides and stops included
    /// [default: 1]
    #[arg(long, value_name = "F", value_parser = pace)]
    pub object_speed: Option<f64>,
}

impl MoverOptions {
    /// The mover the flags describe for `objects` objects; a mover flag without objects is a
    /// usage error.
    pub fn mover(&self, objects: usize) -> Result<Mover, CommandError> {
        let mover = Mover {
            body: self.object_kind.unwrap_or_default(),
            stop_go: self.stop_go,
            shadow: self.shadows,
            pace: self.object_speed.unwrap_or(1.0),
        };
        let given = self.object_kind.is_some()
            || self.stop_go
            || self.shadows
            || self.object_speed.is_some();
        match given && objects == 0 {
            true => Err(CommandError::Usage(
                "--object-kind, --stop-go, --shadows, --object-speed: need --objects 1 or more"
                    .to_owned(),
            )),
            false => Ok(mover),
        }
    }
}

fn pace(text: &str) -> Result<f64, String> {
    let range = |v| (0.05..=4.0).contains(&v);
    values::number(text, range, "must be between 0.05 and 4")
}

fn body(text: &str) -> Result<Body, String> {
    Body::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = Body::ALL.iter().map(|b| b.name()).collect();
        format!("must be one of {} (got \"{text}\")", names.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_flag_is_the_block_and_a_flag_needs_objects() {
        assert_eq!(MoverOptions::default().mover(0).unwrap(), Mover::default());
        let walkers = MoverOptions {
            object_kind: Some(Body::Walker),
            shadows: true,
            ..MoverOptions::default()
        };
        let mover = walkers.mover(2).unwrap();
        assert_eq!(
            (mover.body, mover.stop_go, mover.shadow),
            (Body::Walker, false, true)
        );
        assert!(matches!(walkers.mover(0), Err(CommandError::Usage(_))));
        assert_eq!(body("blob"), Ok(Body::Blob));
        assert!(body("car").unwrap_err().contains("block, walker, blob"));
        assert_eq!(pace("0.1"), Ok(0.1));
        assert!(pace("0").is_err() && pace("5").is_err());
    }
}
