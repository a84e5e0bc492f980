//! The film as numpy arrays: the library keeps one plane per channel, numpy wants
//! pixels interleaved, so each array is one copy into a buffer numpy then owns.

use nimbus::render::film::{Aov, Film, Region};
use nimbus::render::splits::SplitLayer;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The arrays' (height, width): the region's when there is one (the film holds only
/// it), else the frame's.
pub fn image_shape(width: u32, height: u32, region: Option<Region>) -> (usize, usize) {
    match region {
        Some(r) => (r.height() as usize, r.width() as usize),
        None => (height as usize, width as usize),
    }
}

/// A film's R, G, B, A means interleaved, row 0 at the top: the buffer of an
/// (H, W, 4) array.
pub fn interleaved_rgba(film: &Film) -> Vec<f32> {
    let chans = [Aov::R, Aov::G, Aov::B, Aov::A].map(|a| film.channel(a));
    let n = film.width as usize * film.height as usize;
    let mut v = Vec::with_capacity(n * 4);
    for i in 0..n {
        v.extend(chans.iter().map(|c| c[i]));
    }
    v
}

/// A split layer's R, G, B means interleaved: the buffer of an (H, W, 3) array.
fn interleaved_layer(film: &Film, i: usize) -> Vec<f32> {
    let chans = film.layer(i);
    let n = film.width as usize * film.height as usize;
    let mut v = Vec::with_capacity(n * 3);
    for p in 0..n {
        v.extend(chans.iter().map(|c| c[p]));
    }
    v
}

/// An interleaved RGBA buffer as a float32 (H, W, 4) array.
pub fn rgba_array(
    py: Python<'_>,
    rgba: Vec<f32>,
    (h, w): (usize, usize),
) -> PyResult<Bound<'_, PyAny>> {
    Ok(PyArray1::from_vec(py, rgba).reshape([h, w, 4])?.into_any())
}

/// `RenderResult.aovs`: each AOV asked for as an (H, W) array under its channel name,
/// and each split layer asked for as an (H, W, 3) array under its layer name. The film
/// may hold more layers than were asked for (those a written product needs); `layers`
/// is the film's list, in its order.
pub fn aov_dict<'py>(
    py: Python<'py>,
    film: &Film,
    aov_list: &[Aov],
    layers: &[SplitLayer],
    requested_layers: &[SplitLayer],
    (h, w): (usize, usize),
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for a in aov_list {
        let arr = PyArray1::from_vec(py, film.channel(*a)).reshape([h, w])?;
        d.set_item(a.channel_name(), arr)?;
    }
    for (i, l) in layers.iter().enumerate() {
        if requested_layers.contains(l) {
            let arr = PyArray1::from_vec(py, interleaved_layer(film, i)).reshape([h, w, 3])?;
            d.set_item(&l.name, arr)?;
        }
    }
    Ok(d)
}
