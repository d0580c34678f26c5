use super::*;

fn map(pairs: Vec<(&str, Value)>) -> Value {
    Value::Map(
        pairs
            .into_iter()
            .map(|(k, v)| (Value::from(k), v))
            .collect(),
    )
}
fn enc(kind: &str, mut extra: Vec<(&str, Value)>) -> Value {
    extra.push(("kind", Value::from(kind)));
    map(extra)
}
fn byte_array_enc(t: i64) -> Value {
    enc("ByteArray", vec![("type", Value::from(t))])
}
fn data(bytes: Vec<u8>, encs: Vec<Value>) -> Value {
    map(vec![
        ("data", Value::Binary(bytes)),
        ("encoding", Value::Array(encs)),
    ])
}
fn i32s(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

#[test]
fn byte_arrays_of_every_type() {
    let d = data(vec![0xFF, 0x01], vec![byte_array_enc(1)]);
    assert_eq!(decode_data(&d, 2).unwrap(), Values::Int(vec![-1, 1]));
    let d = data(vec![0xFF, 0xFF, 0x02, 0x00], vec![byte_array_enc(2)]);
    assert_eq!(decode_data(&d, 2).unwrap(), Values::Int(vec![-1, 2]));
    let d = data(i32s(&[-7, 70000]), vec![byte_array_enc(3)]);
    assert_eq!(decode_data(&d, 2).unwrap(), Values::Int(vec![-7, 70000]));
    let d = data(vec![0xFF], vec![byte_array_enc(4)]);
    assert_eq!(decode_data(&d, 1).unwrap(), Values::Int(vec![255]));
    let d = data(vec![0xFF, 0xFF], vec![byte_array_enc(5)]);
    assert_eq!(decode_data(&d, 1).unwrap(), Values::Int(vec![65535]));
    let d = data(vec![0xFF; 4], vec![byte_array_enc(6)]);
    assert_eq!(
        decode_data(&d, 1).unwrap(),
        Values::Int(vec![u32::MAX as i64])
    );
    let d = data(1.5f32.to_le_bytes().to_vec(), vec![byte_array_enc(32)]);
    assert_eq!(decode_data(&d, 1).unwrap(), Values::Float(vec![1.5]));
    let d = data((-0.25f64).to_le_bytes().to_vec(), vec![byte_array_enc(33)]);
    assert_eq!(decode_data(&d, 1).unwrap(), Values::Float(vec![-0.25]));
    // a ragged array and an unknown type are refused
    let d = data(vec![1, 2, 3], vec![byte_array_enc(3)]);
    assert!(decode_data(&d, 1).unwrap_err().contains("whole number"));
    let d = data(vec![1], vec![byte_array_enc(9)]);
    assert!(decode_data(&d, 1).unwrap_err().contains("type 9"));
}

#[test]
fn fixed_point_keeps_the_decimal() {
    let d = data(
        i32s(&[42053, -6777, 5, 0]),
        vec![
            enc(
                "FixedPoint",
                vec![("factor", Value::from(1000)), ("srcType", Value::from(33))],
            ),
            byte_array_enc(3),
        ],
    );
    let v = decode_data(&d, 4).unwrap();
    let col = Column {
        name: "x".into(),
        values: v,
        mask: None,
    };
    let mut b = Vec::new();
    let texts: Vec<String> = (0..4)
        .map(|i| {
            col.text(i, &mut b);
            String::from_utf8(b.clone()).unwrap()
        })
        .collect();
    assert_eq!(texts, ["42.053", "-6.777", "0.005", "0.000"]);
    for (i, t) in texts.iter().enumerate() {
        assert_eq!(col.number(i), crate::scene::text::parse_f32(t.as_bytes()));
    }
    // a factor that is no power of ten divides in floating point
    let d = data(
        i32s(&[3]),
        vec![
            enc("FixedPoint", vec![("factor", Value::from(4.0))]),
            byte_array_enc(3),
        ],
    );
    assert_eq!(decode_data(&d, 1).unwrap(), Values::Float(vec![0.75]));
}

#[test]
fn interval_quantization() {
    let d = data(
        vec![0, 1, 2],
        vec![
            enc(
                "IntervalQuantization",
                vec![
                    ("min", Value::from(1.0)),
                    ("max", Value::from(2.0)),
                    ("numSteps", Value::from(3)),
                ],
            ),
            byte_array_enc(4),
        ],
    );
    assert_eq!(
        decode_data(&d, 3).unwrap(),
        Values::Float(vec![1.0, 1.5, 2.0])
    );
}

#[test]
fn run_length_delta_and_packing() {
    // RunLength: (7 x3), (9 x1)
    let d = data(
        i32s(&[7, 3, 9, 1]),
        vec![
            enc("RunLength", vec![("srcSize", Value::from(4))]),
            byte_array_enc(3),
        ],
    );
    assert_eq!(decode_data(&d, 4).unwrap(), Values::Int(vec![7, 7, 7, 9]));
    // a srcSize that disagrees and a huge run are refused
    let d = data(
        i32s(&[7, 3]),
        vec![
            enc("RunLength", vec![("srcSize", Value::from(4))]),
            byte_array_enc(3),
        ],
    );
    assert!(decode_data(&d, 4).unwrap_err().contains("srcSize"));
    let d = data(
        i32s(&[7, i32::MAX, 7, i32::MAX]),
        vec![enc("RunLength", vec![]), byte_array_enc(3)],
    );
    assert!(decode_data(&d, 4).unwrap_err().contains("more than"));
    // Delta from an origin
    let d = data(
        i32s(&[0, 1, 1, -2]),
        vec![
            enc("Delta", vec![("origin", Value::from(10))]),
            byte_array_enc(3),
        ],
    );
    assert_eq!(
        decode_data(&d, 4).unwrap(),
        Values::Int(vec![10, 11, 12, 10])
    );
    // IntegerPacking, signed bytes: 300 = 127 + 127 + 46; -200 = -128 - 72
    let d = data(
        vec![127, 127, 46, 0x80, (-72i8) as u8, 5],
        vec![
            enc(
                "IntegerPacking",
                vec![
                    ("byteCount", Value::from(1)),
                    ("isUnsigned", Value::from(false)),
                    ("srcSize", Value::from(3)),
                ],
            ),
            byte_array_enc(1),
        ],
    );
    assert_eq!(decode_data(&d, 3).unwrap(), Values::Int(vec![300, -200, 5]));
    // unsigned 2-byte: 0 stays a value, 65535 continues
    let d = data(
        [0u16, 65535, 10, 3]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect(),
        vec![
            enc(
                "IntegerPacking",
                vec![
                    ("byteCount", Value::from(2)),
                    ("isUnsigned", Value::from(true)),
                ],
            ),
            byte_array_enc(5),
        ],
    );
    assert_eq!(decode_data(&d, 3).unwrap(), Values::Int(vec![0, 65545, 3]));
}

fn string_array(strings: &str, offsets: &[i32], index: &[i32]) -> Value {
    data(
        i32s(index),
        vec![enc(
            "StringArray",
            vec![
                ("stringData", Value::from(strings)),
                ("offsets", Value::Binary(i32s(offsets))),
                ("offsetEncoding", Value::Array(vec![byte_array_enc(3)])),
                ("dataEncoding", Value::Array(vec![byte_array_enc(3)])),
            ],
        )],
    )
}

#[test]
fn string_arrays_and_masks() {
    let d = string_array("ACAB", &[0, 1, 2, 4], &[0, 2, 1, -1, 0]);
    let v = decode_data(&d, 5).unwrap();
    let col = Column {
        name: "s".into(),
        values: v,
        mask: Some(vec![0, 0, 2, 0, 1]),
    };
    let mut b = Vec::new();
    let got: Vec<Option<String>> = (0..5)
        .map(|i| {
            col.text(i, &mut b)
                .then(|| String::from_utf8(b.clone()).unwrap())
        })
        .collect();
    assert_eq!(got, [Some("A".into()), Some("AB".into()), None, None, None]);
    // an index past the table and offsets past the strings are refused
    let d = string_array("AB", &[0, 1, 2], &[2]);
    assert!(decode_data(&d, 1).unwrap_err().contains("index 2"));
    let d = string_array("AB", &[0, 5], &[0]);
    assert!(decode_data(&d, 1).unwrap_err().contains("offsets"));
}

fn file(columns: Vec<Value>, rows: u64) -> Vec<u8> {
    let cat = map(vec![
        ("name", Value::from("_atom_site")),
        ("rowCount", Value::from(rows)),
        ("columns", Value::Array(columns)),
    ]);
    let block = map(vec![
        ("header", Value::from("TEST")),
        ("categories", Value::Array(vec![cat])),
    ]);
    let root = map(vec![
        ("version", Value::from("0.3.0")),
        ("dataBlocks", Value::Array(vec![block])),
    ]);
    let mut out = Vec::new();
    rmpv::encode::write_value(&mut out, &root).unwrap();
    out
}

fn column(name: &str, d: Value, mask: Option<Value>) -> Value {
    map(vec![
        ("name", Value::from(name)),
        ("data", d),
        ("mask", mask.unwrap_or(Value::Nil)),
    ])
}

#[test]
fn container_errors_are_one_line() {
    let good = column("id", data(i32s(&[1, 2]), vec![byte_array_enc(3)]), None);
    let f = decode(&file(vec![good.clone()], 2)).unwrap();
    let block = f.first_block().unwrap();
    assert_eq!(block.header, "TEST");
    let c = block.category("_atom_site").unwrap();
    assert_eq!(c.column("id").unwrap().values, Values::Int(vec![1, 2]));

    let err = |bytes: &[u8]| decode(bytes).unwrap_err();
    assert!(err(b"\x00garbage").contains("not a BinaryCIF file"));
    assert!(err(b"").contains("not a BinaryCIF file"));
    // a column of the wrong length
    let e = err(&file(vec![good], 3));
    assert!(
        e.contains("_atom_site.id has 2 values, the category has 3 rows"),
        "{e}"
    );
    // an unknown encoding
    let odd = column("x", data(vec![1], vec![enc("Zigzag", vec![])]), None);
    let e = err(&file(vec![odd], 1));
    assert!(e.contains("_atom_site.x: unknown encoding 'Zigzag'"), "{e}");
    // a mask of the wrong length
    let masked = column(
        "x",
        data(vec![1, 2], vec![byte_array_enc(4)]),
        Some(data(vec![0], vec![byte_array_enc(4)])),
    );
    let e = err(&file(vec![masked], 2));
    assert!(e.contains("mask of _atom_site.x has 1 values"), "{e}");
    assert!(!e.contains('\n'));
}
