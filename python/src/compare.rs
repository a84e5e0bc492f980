//! `nimbus.compare` (the library's `nimbus::output::compare`, which `nimbus compare`
//! prints) and `nimbus.read_exr`.

use crate::errors::{Error, SettingsError};
use crate::json::json_to_py;
use nimbus::output::compare::{compare as compare_images, Image};
use nimbus::output::exr::read_all_channels;
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// An image argument of `compare`: an EXR path, or an array (H, W, C) / (H, W) whose
/// channels are R, G, B, A.
fn image(obj: &Bound<'_, PyAny>) -> PyResult<Image> {
    if let Ok(path) = obj.extract::<PathBuf>() {
        return Image::read(&path).map_err(|e| Error::new_err(format!("{e:#}")));
    }
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("asarray", (obj, "float32"))?;
    let arr: PyReadonlyArrayDyn<'_, f32> = arr.extract()?;
    let shape = arr.shape().to_vec();
    let (h, w, c) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] if (1..=4).contains(c) => (*h, *w, *c),
        _ => {
            return Err(SettingsError::new_err(format!(
                "an image array has shape (H, W) or (H, W, C) with C in 1..4, got {shape:?}"
            )))
        }
    };
    let data: Vec<f32> = arr.as_array().iter().copied().collect();
    let channels = ["R", "G", "B", "A"][..c]
        .iter()
        .enumerate()
        .map(|(k, n)| {
            (
                n.to_string(),
                data.iter().skip(k).step_by(c).copied().collect(),
            )
        })
        .collect();
    Ok(Image {
        name: "<array>".into(),
        width: w,
        height: h,
        channels,
    })
}

/// Per-channel error of image `a` against reference `b`, computed by the function
/// `nimbus compare a b --json` prints: each is an EXR path or an array (H, W, C) whose
/// channels are R, G, B, A.
#[pyfunction]
pub fn compare<'py>(
    py: Python<'py>,
    a: Bound<'py, PyAny>,
    b: Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (a, b) = (image(&a)?, image(&b)?);
    let c = py
        .allow_threads(|| compare_images(&a, &b))
        .map_err(|e| SettingsError::new_err(format!("{e:#}")))?;
    json_to_py(py, &c)
}

/// Every channel of an EXR as float32 arrays (H, W), by channel name.
#[pyfunction]
pub fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let (w, h, chans) = py
        .allow_threads(|| read_all_channels(&path))
        .map_err(|e| Error::new_err(format!("{}: {e}", path.display())))?;
    let d = PyDict::new(py);
    for (name, data) in chans {
        let arr: Bound<'py, PyArrayDyn<f32>> = PyArray1::from_vec(py, data).reshape(vec![h, w])?;
        d.set_item(name, arr)?;
    }
    Ok(d)
}
