//! The limits table (docs/architecture.md, section 8) against the code: every `citymesh serve`
//! flag a row names has its default, as clap defines it, in that row's default column, so the
//! documented defaults cannot drift from the flags.

use citymesh::cli::ServeArgs;
use clap::CommandFactory;

/// The rows of section 8's table: (flag / constant, default) columns.
fn limit_rows() -> Vec<(String, String)> {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/architecture.md"))
        .unwrap();
    let section = doc
        .split("\n## 8. Limits")
        .nth(1)
        .expect("docs/architecture.md has a section 8. Limits");
    let section = section.split("\n## ").next().unwrap();
    section
        .lines()
        .filter(|l| l.starts_with('|') && !l.starts_with("|---") && !l.starts_with("| bound |"))
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").collect();
            assert!(cells.len() >= 3, "a row without its columns: {l}");
            (cells[1].to_owned(), cells[2].to_owned())
        })
        .collect()
}

/// A default as the table writes it: integers with thousands separators, no trailing `.0`.
fn as_documented(value: &str) -> String {
    let value = value.strip_suffix(".0").unwrap_or(value);
    if value.len() <= 3 || !value.bytes().all(|b| b.is_ascii_digit()) {
        return value.to_owned();
    }
    let mut out = String::new();
    for (i, c) in value.chars().enumerate() {
        if i > 0 && (value.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The `--flags` a cell names.
fn flags_in(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .flat_map(|code| code.split_whitespace())
        .filter_map(|w| w.strip_prefix("--"))
        .map(|w| {
            w.trim_end_matches(|c: char| !c.is_ascii_alphanumeric())
                .to_owned()
        })
        .collect()
}

#[test]
fn every_documented_serve_default_equals_the_flag() {
    let serve = ServeArgs::command();
    let rows = limit_rows();
    assert!(rows.len() > 40, "{} rows in the limits table", rows.len());
    let mut checked = 0;
    let mut wrong = Vec::new();
    for (flags, defaults) in &rows {
        for flag in flags_in(flags) {
            let Some(arg) = serve
                .get_arguments()
                .find(|a| a.get_long() == Some(flag.as_str()))
            else {
                continue;
            };
            let Some(default) = arg.get_default_values().first() else {
                continue;
            };
            let default = as_documented(&default.to_string_lossy());
            if default == "false" || default == "true" {
                continue;
            }
            if !defaults.contains(&default) {
                wrong.push(format!(
                    "--{flag}: the row says {defaults:?}, the flag {default}"
                ));
            }
            checked += 1;
        }
    }
    assert!(
        wrong.is_empty(),
        "docs/architecture.md section 8 disagrees with the flags:\n{}",
        wrong.join("\n")
    );
    // The flags the table names with a default (counted when this test was written).
    assert!(checked >= 30, "only {checked} defaults checked");
}

#[test]
fn documented_defaults_are_written_as_the_table_writes_them() {
    assert_eq!(as_documented("400000"), "400,000");
    assert_eq!(as_documented("1024"), "1,024");
    assert_eq!(as_documented("25.0"), "25");
    assert_eq!(as_documented("86400"), "86,400");
    assert_eq!(as_documented("150"), "150");
    assert_eq!(
        flags_in("`--header-timeout-s`, `--body-timeout-s` and `--memory-mb 6`"),
        ["header-timeout-s", "body-timeout-s", "memory-mb"]
    );
}
