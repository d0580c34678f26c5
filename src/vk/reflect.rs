//! Just enough SPIR-V reflection to check a pipeline's declared bindings
//! against its shader: for every descriptor (set, binding) the block name,
//! whether it is a uniform or a storage buffer and, for storage buffers,
//! whether the shader may read and/or write it (`readonly` / `writeonly`);
//! and the push-constant block size. The module format is the SPIR-V 1.x
//! specification's (a word stream of `count << 16 | opcode` instructions).

use std::collections::HashMap;

/// How a shader accesses a descriptor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// A uniform buffer (read only, by definition).
    Uniform,
    /// A storage buffer declared `readonly`.
    Read,
    /// A storage buffer declared `writeonly`.
    Write,
    /// A storage buffer without qualifiers (loads, stores or atomics).
    ReadWrite,
    /// A uniform texel buffer (`samplerBuffer`/`usamplerBuffer`, texelFetch):
    /// on lavapipe its fetches are vector gathers, unlike storage loads.
    Texel,
    /// A storage texel buffer (`imageBuffer`) declared `readonly`.
    ImageRead,
    /// A storage texel buffer declared `writeonly`.
    ImageWrite,
    /// A storage texel buffer without qualifiers.
    ImageReadWrite,
}

impl Access {
    pub fn reads(self) -> bool {
        !matches!(self, Access::Write | Access::ImageWrite)
    }
    pub fn writes(self) -> bool {
        matches!(
            self,
            Access::Write | Access::ReadWrite | Access::ImageWrite | Access::ImageReadWrite
        )
    }
    /// Whether the descriptor is a texel buffer (needs a buffer view).
    pub fn is_texel(self) -> bool {
        matches!(
            self,
            Access::Texel | Access::ImageRead | Access::ImageWrite | Access::ImageReadWrite
        )
    }
    pub fn describe(self) -> &'static str {
        match self {
            Access::Uniform => "uniform buffer",
            Access::Read => "readonly storage buffer",
            Access::Write => "writeonly storage buffer",
            Access::ReadWrite => "read-write storage buffer",
            Access::Texel => "uniform texel buffer",
            Access::ImageRead => "readonly storage texel buffer",
            Access::ImageWrite => "writeonly storage texel buffer",
            Access::ImageReadWrite => "read-write storage texel buffer",
        }
    }
}

/// One descriptor of a shader module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Descriptor {
    pub set: u32,
    pub binding: u32,
    /// The GLSL block name (`buffer Spheres { ... }` gives "Spheres").
    pub name: String,
    pub access: Access,
}

/// What reflection found in a module.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Reflection {
    pub descriptors: Vec<Descriptor>,
    /// Bytes of the push-constant block (0 without one).
    pub push_size: u32,
    /// Specialization constant ids the module declares.
    pub spec_ids: Vec<u32>,
}

const MAGIC: u32 = 0x0723_0203;

mod op {
    pub const NAME: u16 = 5;
    pub const TYPE_INT: u16 = 21;
    pub const TYPE_FLOAT: u16 = 22;
    pub const TYPE_VECTOR: u16 = 23;
    pub const TYPE_MATRIX: u16 = 24;
    pub const TYPE_IMAGE: u16 = 25;
    pub const TYPE_SAMPLED_IMAGE: u16 = 27;
    pub const TYPE_ARRAY: u16 = 28;
    pub const TYPE_STRUCT: u16 = 30;
    pub const TYPE_POINTER: u16 = 32;
    pub const CONSTANT: u16 = 43;
    pub const VARIABLE: u16 = 59;
    pub const DECORATE: u16 = 71;
    pub const MEMBER_DECORATE: u16 = 72;
}

mod deco {
    pub const SPEC_ID: u32 = 1;
    pub const BUFFER_BLOCK: u32 = 3;
    pub const ARRAY_STRIDE: u32 = 6;
    pub const NON_WRITABLE: u32 = 24;
    pub const NON_READABLE: u32 = 25;
    pub const BINDING: u32 = 33;
    pub const DESCRIPTOR_SET: u32 = 34;
    pub const OFFSET: u32 = 35;
}

mod class {
    pub const UNIFORM_CONSTANT: u32 = 0;
    pub const UNIFORM: u32 = 2;
    pub const PUSH_CONSTANT: u32 = 9;
    pub const STORAGE_BUFFER: u32 = 12;
}

/// A SPIR-V literal string: UTF-8, NUL-terminated, padded to words.
fn literal_string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

#[derive(Clone, Debug)]
enum Type {
    Scalar(u32),
    Vector(u32, u32),
    Matrix(u32, u32),
    Array(u32, u32, Option<u32>),
    Struct(Vec<u32>),
    /// (dim, sampled: 1 = with a sampler, 2 = storage image)
    Image(u32, u32),
    /// the image type
    SampledImage(u32),
    /// (storage class, pointee)
    Pointer(#[allow(dead_code)] u32, u32),
}

/// Parses `words` (a whole module). Errors name what is malformed.
pub fn reflect(words: &[u32]) -> Result<Reflection, String> {
    if words.len() < 5 || words[0] != MAGIC {
        return Err("not a SPIR-V module (bad magic number)".into());
    }
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut decorations: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
    let mut member_decorations: HashMap<u32, Vec<(u32, u32, u32)>> = HashMap::new();
    let mut types: HashMap<u32, Type> = HashMap::new();
    let mut constants: HashMap<u32, u32> = HashMap::new();
    let mut variables: Vec<(u32, u32, u32)> = Vec::new(); // (type, id, class)
    let mut array_strides: HashMap<u32, u32> = HashMap::new();
    let mut spec_ids = Vec::new();

    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        let opcode = (words[i] & 0xFFFF) as u16;
        if count == 0 || i + count > words.len() {
            return Err(format!("truncated instruction at word {i}"));
        }
        let a = &words[i + 1..i + count];
        match opcode {
            op::NAME if !a.is_empty() => {
                names.insert(a[0], literal_string(&a[1..]));
            }
            op::TYPE_INT | op::TYPE_FLOAT if a.len() >= 2 => {
                types.insert(a[0], Type::Scalar(a[1] / 8));
            }
            op::TYPE_VECTOR if a.len() >= 3 => {
                types.insert(a[0], Type::Vector(a[1], a[2]));
            }
            op::TYPE_MATRIX if a.len() >= 3 => {
                types.insert(a[0], Type::Matrix(a[1], a[2]));
            }
            op::TYPE_ARRAY if a.len() >= 3 => {
                types.insert(a[0], Type::Array(a[1], a[2], None));
            }
            op::TYPE_IMAGE if a.len() >= 7 => {
                types.insert(a[0], Type::Image(a[2], a[6]));
            }
            op::TYPE_SAMPLED_IMAGE if a.len() >= 2 => {
                types.insert(a[0], Type::SampledImage(a[1]));
            }
            op::TYPE_STRUCT if !a.is_empty() => {
                types.insert(a[0], Type::Struct(a[1..].to_vec()));
            }
            op::TYPE_POINTER if a.len() >= 3 => {
                types.insert(a[0], Type::Pointer(a[1], a[2]));
            }
            op::CONSTANT if a.len() >= 3 => {
                constants.insert(a[1], a[2]);
            }
            op::VARIABLE if a.len() >= 3 => variables.push((a[0], a[1], a[2])),
            op::DECORATE if a.len() >= 2 => {
                let value = a.get(2).copied().unwrap_or(0);
                if a[1] == deco::SPEC_ID {
                    spec_ids.push(value);
                }
                if a[1] == deco::ARRAY_STRIDE {
                    array_strides.insert(a[0], value);
                }
                decorations.entry(a[0]).or_default().push((a[1], value));
            }
            op::MEMBER_DECORATE if a.len() >= 3 => {
                let value = a.get(3).copied().unwrap_or(0);
                member_decorations
                    .entry(a[0])
                    .or_default()
                    .push((a[1], a[2], value));
            }
            _ => {}
        }
        i += count;
    }
    // Array lengths are constants defined after the array type's operands
    // were read: resolve them now.
    for t in types.values_mut() {
        if let Type::Array(elem, len_id, len) = t {
            *len = constants.get(len_id).copied();
            let _ = elem;
        }
    }
    let has = |id: u32, d: u32| {
        decorations
            .get(&id)
            .is_some_and(|v| v.iter().any(|x| x.0 == d))
    };
    let value = |id: u32, d: u32| {
        decorations
            .get(&id)
            .and_then(|v| v.iter().find(|x| x.0 == d).map(|x| x.1))
    };

    let mut out = Reflection {
        spec_ids,
        ..Default::default()
    };
    for &(ptr_type, id, storage) in &variables {
        let Some(Type::Pointer(_, pointee)) = types.get(&ptr_type) else {
            continue;
        };
        let block = *pointee;
        if storage == class::PUSH_CONSTANT {
            out.push_size = out.push_size.max(type_size(
                block,
                &types,
                &member_decorations,
                &array_strides,
            ));
            continue;
        }
        if storage == class::UNIFORM_CONSTANT {
            // Texel buffers: images of dimension Buffer (5), named by the variable.
            const DIM_BUFFER: u32 = 5;
            let image = match types.get(&block) {
                Some(Type::SampledImage(img)) => types.get(img),
                t => t,
            };
            let Some(Type::Image(DIM_BUFFER, sampled)) = image else {
                continue;
            };
            let (Some(set), Some(binding)) =
                (value(id, deco::DESCRIPTOR_SET), value(id, deco::BINDING))
            else {
                continue;
            };
            let access = if *sampled == 1 {
                Access::Texel
            } else {
                match (has(id, deco::NON_WRITABLE), has(id, deco::NON_READABLE)) {
                    (true, false) => Access::ImageRead,
                    (false, true) => Access::ImageWrite,
                    _ => Access::ImageReadWrite,
                }
            };
            out.descriptors.push(Descriptor {
                set,
                binding,
                name: names.get(&id).cloned().unwrap_or_default(),
                access,
            });
            continue;
        }
        if storage != class::UNIFORM && storage != class::STORAGE_BUFFER {
            continue;
        }
        let (Some(set), Some(binding)) =
            (value(id, deco::DESCRIPTOR_SET), value(id, deco::BINDING))
        else {
            continue;
        };
        // SPIR-V >= 1.3 storage buffers: StorageBuffer class + Block; older
        // ones: Uniform class + BufferBlock.
        let storage_buffer = storage == class::STORAGE_BUFFER || has(block, deco::BUFFER_BLOCK);
        let access = if !storage_buffer {
            Access::Uniform
        } else {
            let members = match types.get(&block) {
                Some(Type::Struct(m)) => m.len() as u32,
                _ => 0,
            };
            let all_members = |d: u32| {
                members > 0
                    && (0..members).all(|m| {
                        member_decorations
                            .get(&block)
                            .is_some_and(|v| v.iter().any(|x| x.0 == m && x.1 == d))
                    })
            };
            let no_write = has(id, deco::NON_WRITABLE) || all_members(deco::NON_WRITABLE);
            let no_read = has(id, deco::NON_READABLE) || all_members(deco::NON_READABLE);
            match (no_write, no_read) {
                (true, false) => Access::Read,
                (false, true) => Access::Write,
                (false, false) => Access::ReadWrite,
                (true, true) => Access::Read, // neither: treat as a (harmless) read
            }
        };
        out.descriptors.push(Descriptor {
            set,
            binding,
            name: names.get(&block).cloned().unwrap_or_default(),
            access,
        });
    }
    out.descriptors.sort_by_key(|d| (d.set, d.binding));
    Ok(out)
}

/// std430/std140 byte size of a type as laid out by its Offset decorations.
fn type_size(
    id: u32,
    types: &HashMap<u32, Type>,
    members: &HashMap<u32, Vec<(u32, u32, u32)>>,
    strides: &HashMap<u32, u32>,
) -> u32 {
    match types.get(&id) {
        Some(Type::Scalar(b)) => *b,
        Some(Type::Vector(c, n)) => type_size(*c, types, members, strides) * n,
        Some(Type::Matrix(c, n)) => type_size(*c, types, members, strides) * n,
        Some(Type::Array(e, _, len)) => {
            let stride = strides
                .get(&id)
                .copied()
                .unwrap_or_else(|| type_size(*e, types, members, strides));
            stride * len.unwrap_or(0)
        }
        Some(Type::Struct(m)) => m
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let offset = members
                    .get(&id)
                    .and_then(|v| {
                        v.iter()
                            .find(|x| x.0 == k as u32 && x.1 == deco::OFFSET)
                            .map(|x| x.2)
                    })
                    .unwrap_or(0);
                offset + type_size(t, types, members, strides)
            })
            .max()
            .unwrap_or(0),
        _ => 0,
    }
}
