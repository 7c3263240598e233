//! Fixed-length arrays read at their exact length. Serde reads `[T; N]` by taking N elements
//! and the TOML deserializer does not look at the rest, so `eye = [0, 0, 3, 9]` was read as
//! `[0, 0, 3]`; these readers refuse too long arrays as well as too short ones, naming the
//! length the key expects. Used as `#[serde(deserialize_with = "exact")]` (or `exact_opt` on
//! an `Option`, with `default`).

use std::fmt;
use std::marker::PhantomData;

use serde::de::{Deserializer, Error, IgnoredAny, SeqAccess, Visitor};
use serde::Deserialize;

struct Exact<T, const N: usize>(PhantomData<T>);

impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for Exact<T, N> {
    type Value = [T; N];

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "an array of {N} numbers")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; N], A::Error> {
        let mut items = Vec::with_capacity(N);
        while items.len() < N {
            match seq.next_element::<T>()? {
                Some(x) => items.push(x),
                None => return Err(A::Error::invalid_length(items.len(), &self)),
            }
        }
        // the rest only counted (the parser's array limit bounds it)
        let mut len = N;
        while seq.next_element::<IgnoredAny>()?.is_some() {
            len += 1;
        }
        if len != N {
            return Err(A::Error::invalid_length(len, &self));
        }
        items
            .try_into()
            .map_err(|_| A::Error::invalid_length(N, &self))
    }
}

/// `[T; N]` from an array of exactly N elements.
pub fn exact<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(
    d: D,
) -> Result<[T; N], D::Error> {
    d.deserialize_seq(Exact::<T, N>(PhantomData))
}

struct ExactOpt<T, const N: usize>(PhantomData<T>);

impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for ExactOpt<T, N> {
    type Value = Option<[T; N]>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "an array of {N} numbers")
    }

    fn visit_none<E: Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }

    fn visit_unit<E: Error>(self) -> Result<Self::Value, E> {
        Ok(None)
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        exact(d).map(Some)
    }
}

/// `Some([T; N])` from an array of exactly N elements, `None` from a null (a render's
/// record in JSON); absent keys take the field's default.
pub fn exact_opt<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(
    d: D,
) -> Result<Option<[T; N]>, D::Error> {
    d.deserialize_option(ExactOpt::<T, N>(PhantomData))
}
