//! Every named choice reads from text with `FromStr`: each of its `NAMES` parses (and writes
//! itself back where the type has a `name`), and anything else is an `UnknownName` listing them.

use std::str::FromStr;

use visuotact::image::UnknownName;
use visuotact::io::force::ForceField;
use visuotact::io::table::TableFormat;
use visuotact::nn::fit::FieldInputs;
use visuotact::nn::mlp::Algorithm;
use visuotact::signal::fir::Padding;
use visuotact::sim::zoo::ZooKind;
use visuotact::vision::calibration::Preset;
use visuotact::vision::preprocess::Channel;

/// Each name parses; a made-up one is refused with the list.
fn names_parse<T: FromStr<Err = UnknownName>>(names: &[&str], what: &str) -> Vec<T> {
    let parsed: Vec<T> = names.iter().map(|n| n.parse().ok().unwrap()).collect();
    let Err(e) = "no-such-name".parse::<T>() else {
        panic!("a made-up {what} parsed");
    };
    assert_eq!(e.what, what);
    assert_eq!(e.expected, names);
    assert!(e.to_string().contains(&names.join(", ")), "{e}");
    parsed
}

#[test]
fn every_named_choice_reads_its_names_and_refuses_others() {
    let presets: Vec<Preset> = names_parse(Preset::NAMES, "preset");
    assert_eq!(presets, Preset::ALL);
    assert_eq!(Preset::CHOICES[0], "auto");
    assert_eq!(&Preset::CHOICES[1..], Preset::NAMES);
    let zoo: Vec<ZooKind> = names_parse(ZooKind::NAMES, "zoo sensor");
    assert_eq!(zoo, ZooKind::ALL);
    for (c, n) in names_parse::<Channel>(Channel::NAMES, "channel")
        .into_iter()
        .zip(Channel::NAMES)
    {
        assert_eq!(c.name(), *n);
    }
    for (f, n) in names_parse::<ForceField>(ForceField::NAMES, "force packet field")
        .into_iter()
        .zip(ForceField::NAMES)
    {
        assert_eq!(f.name(), *n);
    }
    for (a, n) in names_parse::<Algorithm>(Algorithm::NAMES, "training algorithm")
        .into_iter()
        .zip(Algorithm::NAMES)
    {
        assert_eq!(a.name(), *n);
    }
    let field: Vec<FieldInputs> = names_parse(FieldInputs::NAMES, "field-summary choice");
    assert_eq!(
        field,
        [
            FieldInputs::Auto,
            FieldInputs::Yes,
            FieldInputs::Only,
            FieldInputs::No
        ]
    );
    let pads: Vec<Padding> = names_parse(Padding::NAMES, "padding");
    assert_eq!(pads.len(), 4);
    let formats: Vec<TableFormat> = names_parse(TableFormat::NAMES, "table format");
    assert_eq!(formats, [TableFormat::Csv, TableFormat::Jsonl]);
}

#[test]
fn settings_with_a_parse_read_through_from_str_alike() {
    use visuotact::io::source::SourceSpec;
    use visuotact::vision::features::FeatureSet;
    use visuotact::vision::layout::LayoutChoice;
    assert_eq!(
        "x,y,area".parse::<FeatureSet>().ok(),
        FeatureSet::parse("x,y,area").ok()
    );
    assert_eq!(
        "hex".parse::<LayoutChoice>().ok(),
        LayoutChoice::parse("hex").ok()
    );
    assert!("nonsense".parse::<LayoutChoice>().is_err());
    // Every layout choice's name reads, and they are all there is.
    for n in LayoutChoice::NAMES {
        assert!(n.parse::<LayoutChoice>().is_ok(), "{n}");
    }
    let layouts =
        visuotact::vision::layout::Layout::ALL.map(visuotact::vision::layout::Layout::name);
    assert_eq!(&LayoutChoice::NAMES[1..], layouts);
    assert_eq!(
        "sim:cone".parse::<SourceSpec>(),
        Ok(SourceSpec::Sim("cone".into()))
    );
}
