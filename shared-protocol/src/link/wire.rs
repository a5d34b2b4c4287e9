//! postcard's wire format, written by a serializer of our own that is small in flash.
//!
//! The messages keep their serde derives and postcard's byte format (postcard 1.x, "wire
//! format" of its docs: integers above 8 bits as LEB128 varints, signed ones zig-zagged
//! first, `bool` and `Option` tags as one byte, enum variants and sequence lengths as
//! varints, structs and arrays as their fields in order). What differs is only the code:
//! postcard's serializer inlines a varint encoder with its bounds checks into every field of
//! every message (the images' `service::encode` was 4.3 KB), this one calls three
//! out-of-line helpers (`Writer::byte`, `Writer::varint`, `Writer::bytes`). The same for
//! decoding ([`take_from_bytes`], `Reader`): postcard's rules (varint lengths, `bool` and
//! `Option` tags, UTF-8), varints and byte strings read out of line, single bytes inline
//! (a download chunk's 64 bytes are read in the drive's receive section). The tests below
//! compare both
//! directions with postcard: the bytes for every kind of value the messages use, and the
//! decoded value (or the refusal) for every message type on valid and damaged frames.

use core::fmt;
use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, Visitor};
use serde::ser::{self, Serialize};

/// The output was full (the only way serializing into a slice fails).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Full;

impl fmt::Display for Full {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("serialize buffer full")
    }
}

impl core::error::Error for Full {}

impl ser::Error for Full {
    fn custom<T: fmt::Display>(_msg: T) -> Self {
        Full
    }
}

/// Serializes `value` into `out` in postcard's format; returns the length written.
pub fn to_slice<T: Serialize + ?Sized>(value: &T, out: &mut [u8]) -> Result<usize, Full> {
    let mut w = Writer { out, len: 0 };
    value.serialize(&mut w)?;
    Ok(w.len)
}

/// A postcard serializer into a slice.
pub struct Writer<'a> {
    out: &'a mut [u8],
    len: usize,
}

impl Writer<'_> {
    /// One raw byte.
    #[inline(never)]
    fn byte(&mut self, b: u8) -> Result<(), Full> {
        *self.out.get_mut(self.len).ok_or(Full)? = b;
        self.len += 1;
        Ok(())
    }

    /// An unsigned integer as a LEB128 varint (postcard's for every width above 8 bits).
    #[inline(never)]
    fn varint(&mut self, mut v: u64) -> Result<(), Full> {
        while v >= 0x80 {
            self.byte(v as u8 | 0x80)?;
            v >>= 7;
        }
        self.byte(v as u8)
    }

    /// A length-prefixed byte string (`str`, `[u8]` as bytes).
    #[inline(never)]
    fn bytes(&mut self, b: &[u8]) -> Result<(), Full> {
        self.varint(b.len() as u64)?;
        for &x in b {
            self.byte(x)?;
        }
        Ok(())
    }
}

/// Zig-zag of a signed integer (postcard: `(n << 1) ^ (n >> 63)` at the value's width,
/// the same number at any width for a value that fits).
fn zig_zag(n: i64) -> u64 {
    ((n << 1) ^ (n >> 63)) as u64
}

impl<'a> ser::Serializer for &mut Writer<'a> {
    type Ok = ();
    type Error = Full;
    type SerializeSeq = Self;
    type SerializeTuple = Self;
    type SerializeTupleStruct = Self;
    type SerializeTupleVariant = Self;
    type SerializeMap = Self;
    type SerializeStruct = Self;
    type SerializeStructVariant = Self;

    fn is_human_readable(&self) -> bool {
        false
    }
    fn serialize_bool(self, v: bool) -> Result<(), Full> {
        self.byte(u8::from(v))
    }
    fn serialize_i8(self, v: i8) -> Result<(), Full> {
        self.byte(v as u8)
    }
    fn serialize_i16(self, v: i16) -> Result<(), Full> {
        self.varint(zig_zag(i64::from(v)))
    }
    fn serialize_i32(self, v: i32) -> Result<(), Full> {
        self.varint(zig_zag(i64::from(v)))
    }
    fn serialize_i64(self, v: i64) -> Result<(), Full> {
        self.varint(zig_zag(v))
    }
    fn serialize_u8(self, v: u8) -> Result<(), Full> {
        self.byte(v)
    }
    fn serialize_u16(self, v: u16) -> Result<(), Full> {
        self.varint(u64::from(v))
    }
    fn serialize_u32(self, v: u32) -> Result<(), Full> {
        self.varint(u64::from(v))
    }
    fn serialize_u64(self, v: u64) -> Result<(), Full> {
        self.varint(v)
    }
    fn serialize_f32(self, v: f32) -> Result<(), Full> {
        v.to_le_bytes().iter().try_for_each(|&b| self.byte(b))
    }
    fn serialize_f64(self, v: f64) -> Result<(), Full> {
        v.to_le_bytes().iter().try_for_each(|&b| self.byte(b))
    }
    fn serialize_char(self, v: char) -> Result<(), Full> {
        let mut buf = [0u8; 4];
        self.bytes(v.encode_utf8(&mut buf).as_bytes())
    }
    fn serialize_str(self, v: &str) -> Result<(), Full> {
        self.bytes(v.as_bytes())
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<(), Full> {
        self.bytes(v)
    }
    fn serialize_none(self) -> Result<(), Full> {
        self.byte(0)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<(), Full> {
        self.byte(1)?;
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), Full> {
        Ok(())
    }
    fn serialize_unit_struct(self, _name: &'static str) -> Result<(), Full> {
        Ok(())
    }
    fn serialize_unit_variant(
        self,
        _name: &'static str,
        index: u32,
        _variant: &'static str,
    ) -> Result<(), Full> {
        self.varint(u64::from(index))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        index: u32,
        _variant: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        self.varint(u64::from(index))?;
        value.serialize(self)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Self, Full> {
        // postcard needs the length up front (it refuses a sequence without one).
        self.varint(len.ok_or(Full)? as u64)?;
        Ok(self)
    }
    fn serialize_tuple(self, _len: usize) -> Result<Self, Full> {
        Ok(self)
    }
    fn serialize_tuple_struct(self, _name: &'static str, _len: usize) -> Result<Self, Full> {
        Ok(self)
    }
    fn serialize_tuple_variant(
        self,
        _name: &'static str,
        index: u32,
        _variant: &'static str,
        _len: usize,
    ) -> Result<Self, Full> {
        self.varint(u64::from(index))?;
        Ok(self)
    }
    fn serialize_map(self, len: Option<usize>) -> Result<Self, Full> {
        self.varint(len.ok_or(Full)? as u64)?;
        Ok(self)
    }
    fn serialize_struct(self, _name: &'static str, _len: usize) -> Result<Self, Full> {
        Ok(self)
    }
    fn serialize_struct_variant(
        self,
        _name: &'static str,
        index: u32,
        _variant: &'static str,
        _len: usize,
    ) -> Result<Self, Full> {
        self.varint(u64::from(index))?;
        Ok(self)
    }
    fn collect_str<T: fmt::Display + ?Sized>(self, _value: &T) -> Result<(), Full> {
        // No message formats a value into a string; refused rather than linking core::fmt.
        Err(Full)
    }
}

impl ser::SerializeSeq for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeTuple for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeTupleStruct for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeTupleVariant for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeMap for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Full> {
        key.serialize(&mut **self)
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeStruct for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        _key: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

impl ser::SerializeStructVariant for &mut Writer<'_> {
    type Ok = ();
    type Error = Full;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        _key: &'static str,
        value: &T,
    ) -> Result<(), Full> {
        value.serialize(&mut **self)
    }
    fn end(self) -> Result<(), Full> {
        Ok(())
    }
}

/// Why bytes did not deserialize (postcard's errors, not told apart: every one makes the
/// frame a [`super::FrameError::Message`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bad;

impl fmt::Display for Bad {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("not a message")
    }
}

impl core::error::Error for Bad {}

impl de::Error for Bad {
    fn custom<T: fmt::Display>(_msg: T) -> Self {
        Bad
    }
}

/// Deserializes a `T` from the front of `bytes` in postcard's format (what
/// `postcard::take_from_bytes` accepts, and nothing else); returns it and the bytes left.
pub fn take_from_bytes<T: DeserializeOwned>(bytes: &[u8]) -> Result<(T, &[u8]), Bad> {
    let mut r = Reader { rest: bytes };
    let t = T::deserialize(&mut r)?;
    Ok((t, r.rest))
}

/// A postcard deserializer over a slice.
pub struct Reader<'de> {
    rest: &'de [u8],
}

/// postcard's varint limits per width: at most `(bits + 6) / 7` bytes, and the last one
/// at most `2^(bits % 7) - 1` (so that the value fits the width).
const fn limits(bits: u32) -> (u32, u8) {
    (bits.div_ceil(7), ((1u32 << (bits % 7)) - 1) as u8)
}

impl<'de> Reader<'de> {
    /// Inlined (as small as a call): a download chunk's 64 bytes are read one by one in
    /// the drive's receive section, against the PWM interrupt.
    #[inline]
    fn pop(&mut self) -> Result<u8, Bad> {
        let (&b, rest) = self.rest.split_first().ok_or(Bad)?;
        self.rest = rest;
        Ok(b)
    }

    /// A varint of a `bits`-wide unsigned integer, refused as postcard refuses it (too
    /// many bytes, or a last byte that overflows the width).
    #[inline(never)]
    fn varint(&mut self, bits: u32) -> Result<u64, Bad> {
        let (max_bytes, max_last) = limits(bits);
        let mut out = 0u64;
        for i in 0..max_bytes {
            let b = self.pop()?;
            out |= u64::from(b & 0x7F) << (7 * i);
            if b & 0x80 == 0 {
                if i == max_bytes - 1 && b > max_last {
                    return Err(Bad);
                }
                return Ok(out);
            }
        }
        Err(Bad)
    }

    fn varint_u16(&mut self) -> Result<u16, Bad> {
        Ok(self.varint(16)? as u16)
    }

    fn varint_u32(&mut self) -> Result<u32, Bad> {
        Ok(self.varint(32)? as u32)
    }

    /// A length: postcard reads it as the platform's `usize`.
    fn len(&mut self) -> Result<usize, Bad> {
        Ok(self.varint(usize::BITS)? as usize)
    }

    #[inline(never)]
    fn take(&mut self, n: usize) -> Result<&'de [u8], Bad> {
        if n > self.rest.len() {
            return Err(Bad);
        }
        let (t, rest) = self.rest.split_at(n);
        self.rest = rest;
        Ok(t)
    }
}

fn un_zig_zag(n: u64) -> i64 {
    ((n >> 1) as i64) ^ (-((n & 1) as i64))
}

struct Seq<'a, 'de> {
    r: &'a mut Reader<'de>,
    len: usize,
}

impl<'de> de::SeqAccess<'de> for Seq<'_, 'de> {
    type Error = Bad;
    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, Bad> {
        if self.len == 0 {
            return Ok(None);
        }
        self.len -= 1;
        seed.deserialize(&mut *self.r).map(Some)
    }
    fn size_hint(&self) -> Option<usize> {
        // As postcard: no hint larger than the bytes left.
        (self.len <= self.r.rest.len()).then_some(self.len)
    }
}

impl<'de> de::MapAccess<'de> for Seq<'_, 'de> {
    type Error = Bad;
    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, Bad> {
        if self.len == 0 {
            return Ok(None);
        }
        self.len -= 1;
        seed.deserialize(&mut *self.r).map(Some)
    }
    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Bad> {
        seed.deserialize(&mut *self.r)
    }
    fn size_hint(&self) -> Option<usize> {
        Some(self.len)
    }
}

impl<'de> de::Deserializer<'de> for &mut Reader<'de> {
    type Error = Bad;

    fn is_human_readable(&self) -> bool {
        false
    }
    fn deserialize_any<V: Visitor<'de>>(self, _v: V) -> Result<V::Value, Bad> {
        Err(Bad)
    }
    fn deserialize_bool<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        match self.pop()? {
            0 => v.visit_bool(false),
            1 => v.visit_bool(true),
            _ => Err(Bad),
        }
    }
    fn deserialize_i8<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_i8(self.pop()? as i8)
    }
    fn deserialize_i16<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_i16(un_zig_zag(u64::from(self.varint_u16()?)) as i16)
    }
    fn deserialize_i32<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_i32(un_zig_zag(u64::from(self.varint_u32()?)) as i32)
    }
    fn deserialize_i64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_i64(un_zig_zag(self.varint(64)?))
    }
    fn deserialize_u8<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_u8(self.pop()?)
    }
    fn deserialize_u16<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_u16(self.varint_u16()?)
    }
    fn deserialize_u32<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_u32(self.varint_u32()?)
    }
    fn deserialize_u64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_u64(self.varint(64)?)
    }
    fn deserialize_f32<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let b = self.take(4)?;
        let mut a = [0u8; 4];
        a.copy_from_slice(b);
        v.visit_f32(f32::from_le_bytes(a))
    }
    fn deserialize_f64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        v.visit_f64(f64::from_le_bytes(a))
    }
    fn deserialize_char<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let n = self.len()?;
        if n > 4 {
            return Err(Bad);
        }
        let b = self.take(n)?;
        let c = core::str::from_utf8(b)
            .map_err(|_| Bad)?
            .chars()
            .next()
            .ok_or(Bad)?;
        v.visit_char(c)
    }
    fn deserialize_str<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let n = self.len()?;
        let b = self.take(n)?;
        v.visit_borrowed_str(core::str::from_utf8(b).map_err(|_| Bad)?)
    }
    fn deserialize_string<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        self.deserialize_str(v)
    }
    fn deserialize_bytes<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let n = self.len()?;
        v.visit_borrowed_bytes(self.take(n)?)
    }
    fn deserialize_byte_buf<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        self.deserialize_bytes(v)
    }
    fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        match self.pop()? {
            0 => v.visit_none(),
            1 => v.visit_some(self),
            _ => Err(Bad),
        }
    }
    fn deserialize_unit<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        v.visit_unit()
    }
    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_unit()
    }
    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_newtype_struct(self)
    }
    fn deserialize_seq<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let len = self.len()?;
        v.visit_seq(Seq { r: self, len })
    }
    fn deserialize_tuple<V: Visitor<'de>>(self, len: usize, v: V) -> Result<V::Value, Bad> {
        v.visit_seq(Seq { r: self, len })
    }
    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        len: usize,
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_seq(Seq { r: self, len })
    }
    fn deserialize_map<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Bad> {
        let len = self.len()?;
        v.visit_map(Seq { r: self, len })
    }
    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_seq(Seq {
            r: self,
            len: fields.len(),
        })
    }
    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_enum(self)
    }
    fn deserialize_identifier<V: Visitor<'de>>(self, _v: V) -> Result<V::Value, Bad> {
        Err(Bad)
    }
    fn deserialize_ignored_any<V: Visitor<'de>>(self, _v: V) -> Result<V::Value, Bad> {
        Err(Bad)
    }
}

impl<'de> de::EnumAccess<'de> for &mut Reader<'de> {
    type Error = Bad;
    type Variant = Self;
    fn variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<(S::Value, Self), Bad> {
        let index = self.varint_u32()?;
        let v = seed.deserialize(index.into_deserializer())?;
        Ok((v, self))
    }
}

impl<'de> de::VariantAccess<'de> for &mut Reader<'de> {
    type Error = Bad;
    fn unit_variant(self) -> Result<(), Bad> {
        Ok(())
    }
    fn newtype_variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<S::Value, Bad> {
        seed.deserialize(self)
    }
    fn tuple_variant<V: Visitor<'de>>(self, len: usize, v: V) -> Result<V::Value, Bad> {
        v.visit_seq(Seq { r: self, len })
    }
    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Bad> {
        v.visit_seq(Seq {
            r: self,
            len: fields.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Serialize;

    fn same<T: Serialize + core::fmt::Debug>(v: &T) -> std::vec::Vec<u8> {
        let mut ours = [0u8; 256];
        let mut theirs = [0u8; 256];
        let n = to_slice(v, &mut ours).unwrap();
        let p = postcard::to_slice(v, &mut theirs).unwrap();
        assert_eq!(&ours[..n], &*p, "{v:?}");
        ours[..n].to_vec()
    }

    #[derive(Debug, Serialize)]
    enum E {
        Unit,
        New(u8),
        Tuple(i16, u32),
        Struct { a: u64, b: Option<i32> },
    }

    #[derive(Debug, Serialize)]
    struct S {
        flag: bool,
        small: i8,
        arr: [u16; 3],
        v: heapless::Vec<i16, 4>,
        s: heapless::String<8>,
        t: (u8, u16),
        e: [E; 4],
        f: f32,
    }

    #[test]
    fn integers_match_postcard_at_every_varint_boundary() {
        for v in [
            0u64,
            1,
            127,
            128,
            255,
            256,
            16_383,
            16_384,
            65_535,
            65_536,
            u32::MAX as u64,
        ]
        .into_iter()
        .chain([1u64 << 35, 1 << 49, 1 << 56, 1 << 63, u64::MAX])
        {
            same(&v);
            if let Ok(x) = u32::try_from(v) {
                same(&x);
            }
            if let Ok(x) = u16::try_from(v) {
                same(&x);
            }
        }
        for v in [
            0i64,
            1,
            -1,
            63,
            -64,
            64,
            -65,
            8191,
            -8192,
            32_767,
            -32_768,
            i64::MAX,
            i64::MIN,
        ] {
            same(&v);
            if let Ok(x) = i32::try_from(v) {
                same(&x);
            }
            if let Ok(x) = i16::try_from(v) {
                same(&x);
            }
            if let Ok(x) = i8::try_from(v) {
                same(&x);
            }
        }
    }

    #[test]
    fn every_shape_matches_postcard() {
        let s = S {
            flag: true,
            small: -3,
            arr: [1, 300, 65_535],
            v: heapless::Vec::from_slice(&[-1, 2, -300]).unwrap(),
            s: heapless::String::try_from("abc").unwrap(),
            t: (7, 1000),
            e: [
                E::Unit,
                E::New(9),
                E::Tuple(-200, 70_000),
                E::Struct {
                    a: 1 << 40,
                    b: Some(-5),
                },
            ],
            f: 1.5,
        };
        // Golden bytes: postcard's, spelled out.
        let bytes = same(&s);
        assert_eq!(
            bytes,
            [
                1, 0xFD, 1, 0xAC, 2, 0xFF, 0xFF, 3, 3, 1, 4, 0xD7, 4, 3, b'a', b'b', b'c', 7, 0xE8,
                7, 0, 1, 9, 2, 0x8F, 3, 0xF0, 0xA2, 4, 3, 0x80, 0x80, 0x80, 0x80, 0x80, 0x20, 1, 9,
                0, 0, 0xC0, 0x3F
            ]
        );
        same(&Some(E::Struct { a: 0, b: None }));
        same(&'é');
    }

    #[test]
    fn a_full_buffer_is_an_error_never_a_short_write() {
        let mut out = [0u8; 2];
        assert_eq!(to_slice(&[1u8, 2, 3], &mut out), Err(Full));
        assert_eq!(to_slice(&300u16, &mut out), Ok(2));
        assert_eq!(to_slice(&70_000u32, &mut out), Err(Full));
    }

    /// Our decoder and postcard's agree on `bytes` read as a `T`: the same value and rest,
    /// or both refuse.
    fn decodes_alike<T>(bytes: &[u8])
    where
        T: DeserializeOwned + PartialEq + core::fmt::Debug,
    {
        let ours = take_from_bytes::<T>(bytes).ok();
        let theirs = postcard::take_from_bytes::<T>(bytes).ok();
        assert_eq!(ours, theirs, "{bytes:02x?}");
    }

    fn all_types(bytes: &[u8]) {
        use crate::link::frame::Frame;
        use crate::link::{DriveMsg, PlcMsg};
        use crate::service::{Answer, Request};
        decodes_alike::<Frame<DriveMsg>>(bytes);
        decodes_alike::<Frame<PlcMsg>>(bytes);
        decodes_alike::<Frame<Request>>(bytes);
        decodes_alike::<Frame<Answer>>(bytes);
        decodes_alike::<S2>(bytes);
    }

    #[derive(Debug, PartialEq, serde::Deserialize)]
    struct S2 {
        a: u16,
        b: i32,
        c: u64,
        d: i64,
        e: bool,
        f: Option<u8>,
        g: heapless::String<4>,
        h: char,
        i: heapless::Vec<u32, 3>,
    }

    #[test]
    fn varints_at_the_limits_decode_as_postcard_decodes_them() {
        for bytes in [
            &[0x83, 0x80, 0x03][..],
            &[0xFF, 0xFF, 0x03],
            &[0xFF, 0xFF, 0x04],
            &[0x80, 0x80, 0x80, 0x00],
            &[0xFF, 0xFF, 0xFF, 0xFF, 0x0F],
            &[0xFF, 0xFF, 0xFF, 0xFF, 0x10],
            &[0x80, 0x00],
            &[0x80],
        ] {
            decodes_alike::<u16>(bytes);
            decodes_alike::<i16>(bytes);
            decodes_alike::<u32>(bytes);
            decodes_alike::<i32>(bytes);
            decodes_alike::<u64>(bytes);
            decodes_alike::<heapless::Vec<u8, 4>>(bytes);
        }
        for b in 0..=255u8 {
            decodes_alike::<bool>(&[b]);
            decodes_alike::<Option<u8>>(&[b, 1]);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(4000))]
        /// Random frames (a variant index likely to exist, then small and large bytes).
        #[test]
        fn random_frames_decode_as_postcard_decodes_them(
            head in proptest::collection::vec(0u8..4, 2..3),
            variant in 0u8..24,
            tail in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..60),
        ) {
            let mut bytes = head;
            bytes.push(variant);
            bytes.extend_from_slice(&tail);
            all_types(&bytes);
            all_types(&tail);
        }

        /// Every encodable value of the shapes above round-trips through both.
        #[test]
        fn small_bytes_decode_as_postcard_decodes_them(
            bytes in proptest::collection::vec(0u8..3, 0..40),
        ) {
            all_types(&bytes);
        }
    }
}
