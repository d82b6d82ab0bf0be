//! The element types the CNN's convolution blocks compute in ([`super::convnet`]):
//! float64, or float32 for twice the lanes per vector. [`Real`] is what the kernels
//! ([`super::conv1d`]) and the aligned buffers ([`super::aligned`]) need of them; on
//! x86-64, [`Vector`] and [`Wide`] are their AVX and AVX-512 vectors.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, Mul, Sub};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// f32 or f64: IEEE arithmetic (no operation fused unless written as [`Real::mul_add`]),
/// the same in a scalar and in a SIMD lane, so that every path computes the same bits.
pub(crate) trait Real:
    sealed::Sealed
    + Copy
    + Default
    + Debug
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + AddAssign
    + Sum
{
    /// Lanes of a 256-bit (AVX) vector: the width of the portable path's tiles and the
    /// number of partial sums of [`super::conv1d::lane_sum`]; channels are padded to a
    /// multiple of it. At most [`MAX_LANES`].
    const LANES: usize;
    /// Lanes of a 512-bit (AVX-512) vector.
    const LANES_512: usize;
    const ZERO: Self;
    const ONE: Self;
    /// The AVX and AVX-512 vectors of this type.
    #[cfg(target_arch = "x86_64")]
    type V256: Vector<Elem = Self>;
    #[cfg(target_arch = "x86_64")]
    type V512: Wide<Elem = Self>;
    /// `self·a + b` with one rounding.
    fn mul_add(self, a: Self, b: Self) -> Self;
    fn sqrt(self) -> Self;
    /// The nearest value of this type (exact for f64).
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
}

/// The largest [`Real::LANES`].
pub(crate) const MAX_LANES: usize = 8;

macro_rules! real {
    ($t:ty, $v256:ty, $v512:ty) => {
        impl Real for $t {
            const LANES: usize = 32 / std::mem::size_of::<$t>();
            const LANES_512: usize = 64 / std::mem::size_of::<$t>();
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[cfg(target_arch = "x86_64")]
            type V256 = $v256;
            #[cfg(target_arch = "x86_64")]
            type V512 = $v512;
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                <$t>::mul_add(self, a, b)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::{__m256, __m256d, __m512, __m512d};
#[cfg(target_arch = "x86_64")]
pub(crate) use vectors::{Vector, Wide};

real!(f64, __m256d, __m512d);
real!(f32, __m256, __m512);

/// The AVX and AVX-512 vectors of [`Real`].
#[cfg(target_arch = "x86_64")]
mod vectors {
    use super::{Real, MAX_LANES};
    use std::arch::x86_64::*;

    /// A SIMD vector of `LANES` values of `Elem`, as the convolution's tiles use it. The
    /// methods are the intrinsics of one instruction each.
    ///
    /// # Safety (every method)
    /// The CPU must have the target features of the vector's instructions (AVX2 and
    /// FMA for 256 bits, AVX-512F for 512), and a pointer must be valid for `LANES`
    /// values.
    pub(crate) trait Vector: Copy {
        type Elem: Real;
        const LANES: usize;
        unsafe fn zero() -> Self;
        unsafe fn splat(x: Self::Elem) -> Self;
        unsafe fn load(p: *const Self::Elem) -> Self;
        unsafe fn store(self, p: *mut Self::Elem);
        /// `a·b + c` with one rounding.
        unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self;
    }

    /// An AVX-512 vector: the element-wise arithmetic of LayerNorm and LeakyReLU.
    ///
    /// # Safety (every method)
    /// The CPU must have AVX-512F.
    pub(crate) trait Wide: Vector {
        unsafe fn sub(a: Self, b: Self) -> Self;
        unsafe fn mul(a: Self, b: Self) -> Self;
        unsafe fn add(a: Self, b: Self) -> Self;
        /// `y` where `y >= 0` (NaN fails it, as in the scalar `if`), else `y·slope`.
        unsafe fn leaky(y: Self, slope: Self) -> Self;
        /// Σ over the lanes of `vectors` in the partial sums of `lane_sum`
        /// (`conv1d::tiles`): partial sum j (the first [`Real::LANES`] of the array)
        /// takes lane j of each 256-bit half, half after half, vector after vector.
        unsafe fn lane_partials(vectors: &[Self]) -> [Self::Elem; MAX_LANES];
    }

    /// [`Vector`] for `$vec`, compiled for `$feature`, with these intrinsics.
    macro_rules! vector {
        (
            $vec:ty, $elem:ty, $feature:literal,
            $setzero:ident, $set1:ident, $loadu:ident, $storeu:ident, $fmadd:ident
        ) => {
            impl Vector for $vec {
                type Elem = $elem;
                const LANES: usize = std::mem::size_of::<$vec>() / std::mem::size_of::<$elem>();
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn zero() -> Self {
                    $setzero()
                }
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn splat(x: $elem) -> Self {
                    $set1(x)
                }
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn load(p: *const $elem) -> Self {
                    // SAFETY: the caller's contract.
                    unsafe { $loadu(p) }
                }
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn store(self, p: *mut $elem) {
                    // SAFETY: the caller's contract.
                    unsafe { $storeu(p, self) }
                }
                #[inline]
                #[target_feature(enable = $feature)]
                unsafe fn fmadd(a: Self, b: Self, c: Self) -> Self {
                    $fmadd(a, b, c)
                }
            }
        };
    }

    vector!(
        __m256d,
        f64,
        "avx2,fma",
        _mm256_setzero_pd,
        _mm256_set1_pd,
        _mm256_loadu_pd,
        _mm256_storeu_pd,
        _mm256_fmadd_pd
    );
    vector!(
        __m256,
        f32,
        "avx2,fma",
        _mm256_setzero_ps,
        _mm256_set1_ps,
        _mm256_loadu_ps,
        _mm256_storeu_ps,
        _mm256_fmadd_ps
    );
    vector!(
        __m512d,
        f64,
        "avx512f",
        _mm512_setzero_pd,
        _mm512_set1_pd,
        _mm512_loadu_pd,
        _mm512_storeu_pd,
        _mm512_fmadd_pd
    );
    vector!(
        __m512,
        f32,
        "avx512f",
        _mm512_setzero_ps,
        _mm512_set1_ps,
        _mm512_loadu_ps,
        _mm512_storeu_ps,
        _mm512_fmadd_ps
    );

    /// [`Wide`] for `$vec`: these intrinsics, and `$halves` (of `$v`) its two 256-bit
    /// halves, added up (`$add256`) into partial sums stored with `$storeu256`.
    macro_rules! wide {
        (
            $vec:ty, $half:ty, $sub:ident, $mul:ident, $add:ident, $cmp_mask:ident,
            $blend:ident, $setzero256:ident, $add256:ident, $storeu256:ident,
            $v:ident => $halves:expr
        ) => {
            impl Wide for $vec {
                #[inline]
                #[target_feature(enable = "avx512f")]
                unsafe fn sub(a: Self, b: Self) -> Self {
                    $sub(a, b)
                }
                #[inline]
                #[target_feature(enable = "avx512f")]
                unsafe fn mul(a: Self, b: Self) -> Self {
                    $mul(a, b)
                }
                #[inline]
                #[target_feature(enable = "avx512f")]
                unsafe fn add(a: Self, b: Self) -> Self {
                    $add(a, b)
                }
                #[inline]
                #[target_feature(enable = "avx512f")]
                unsafe fn leaky(y: Self, slope: Self) -> Self {
                    let keep = $cmp_mask::<_CMP_GE_OQ>(y, Self::zero());
                    $blend(keep, $mul(y, slope), y)
                }
                #[inline]
                #[target_feature(enable = "avx512f")]
                unsafe fn lane_partials(vectors: &[Self]) -> [Self::Elem; MAX_LANES] {
                    let mut acc = $setzero256();
                    for &$v in vectors {
                        let (lo, hi): ($half, $half) = $halves;
                        acc = $add256(acc, lo);
                        acc = $add256(acc, hi);
                    }
                    let mut parts = [<Self::Elem as Real>::ZERO; MAX_LANES];
                    // SAFETY: `parts` has room for the 256 bits of `acc`.
                    unsafe { $storeu256(parts.as_mut_ptr(), acc) };
                    parts
                }
            }
        };
    }

    wide!(
        __m512d,
        __m256d,
        _mm512_sub_pd,
        _mm512_mul_pd,
        _mm512_add_pd,
        _mm512_cmp_pd_mask,
        _mm512_mask_blend_pd,
        _mm256_setzero_pd,
        _mm256_add_pd,
        _mm256_storeu_pd,
        v => (_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v))
    );
    wide!(
        __m512,
        __m256,
        _mm512_sub_ps,
        _mm512_mul_ps,
        _mm512_add_ps,
        _mm512_cmp_ps_mask,
        _mm512_mask_blend_ps,
        _mm256_setzero_ps,
        _mm256_add_ps,
        _mm256_storeu_ps,
        // the upper half through the float64 view (an AVX-512F instruction; the float32
        // one needs AVX-512DQ)
        v => (
            _mm512_castps512_ps256(v),
            _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v)))
        )
    );
}
