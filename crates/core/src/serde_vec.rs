//! Strict deserialisation of small vectors in configuration files: `[x, y, z]` must
//! have exactly three numbers (TOML readers otherwise ignore extra elements, so a typo
//! like `[0, 1, 0, 5]` would pass silently).
//!
//! Use with `#[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]`.

use glam::{Vec2, Vec3};
use serde::Deserialize;
use serde::de::{Deserializer, Error};

fn exact<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f32; N], D::Error> {
    let v = Vec::<f32>::deserialize(d)?;
    <[f32; N]>::try_from(v.as_slice())
        .map_err(|_| D::Error::custom(format!("expected an array of exactly {N} numbers, found {}", v.len())))
}

/// A `Vec3` written as exactly `[x, y, z]`.
pub fn vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    exact::<D, 3>(d).map(Vec3::from)
}

/// A `Vec2` written as exactly `[x, y]`.
pub fn vec2<'de, D: Deserializer<'de>>(d: D) -> Result<Vec2, D::Error> {
    exact::<D, 2>(d).map(Vec2::from)
}

/// A list of points, each exactly `[x, y]`.
pub fn points2<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f32; 2]>, D::Error> {
    let v = Vec::<Vec<f32>>::deserialize(d)?;
    v.iter()
        .enumerate()
        .map(|(i, p)| {
            <[f32; 2]>::try_from(p.as_slice()).map_err(|_| {
                D::Error::custom(format!(
                    "point {i}: expected an array of exactly 2 numbers, found {}",
                    p.len()
                ))
            })
        })
        .collect()
}

/// Lists of point lists (e.g. strokes), each point exactly `[x, y]`.
pub fn point_lists2<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<[f32; 2]>>, D::Error> {
    let v = Vec::<Vec<Vec<f32>>>::deserialize(d)?;
    v.iter()
        .enumerate()
        .map(|(l, list)| {
            list.iter()
                .enumerate()
                .map(|(i, p)| {
                    <[f32; 2]>::try_from(p.as_slice()).map_err(|_| {
                        D::Error::custom(format!(
                            "list {l}, point {i}: expected an array of exactly 2 numbers, found {}",
                            p.len()
                        ))
                    })
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::de::value::{Error as ValueError, SeqDeserializer};

    fn seq(v: Vec<f32>) -> SeqDeserializer<std::vec::IntoIter<f32>, ValueError> {
        SeqDeserializer::new(v.into_iter())
    }

    #[test]
    fn exactly_n_numbers() {
        assert_eq!(vec3(seq(vec![1.0, 2.0, 3.0])).unwrap(), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(
            vec3(seq(vec![1.0, 2.0, 3.0, 4.0])).unwrap_err().to_string(),
            "expected an array of exactly 3 numbers, found 4"
        );
        assert_eq!(
            vec2(seq(vec![1.0])).unwrap_err().to_string(),
            "expected an array of exactly 2 numbers, found 1"
        );
        assert_eq!(vec2(seq(vec![1.0, 2.0])).unwrap(), Vec2::new(1.0, 2.0));
    }
}
