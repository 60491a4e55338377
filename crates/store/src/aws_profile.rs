//! Settings of an AWS profile from the shared files (`~/.aws/credentials`, `~/.aws/config`, or
//! `AWS_SHARED_CREDENTIALS_FILE` / `AWS_CONFIG_FILE`), for the settings the environment does not
//! give: the environment wins, as in the AWS command-line tools. `AWS_PROFILE` picks the
//! profile (`default` otherwise).

use std::collections::HashMap;
use std::path::PathBuf;

/// The settings `s3://` reads use, by the name the AWS files give them.
pub const KEYS: [&str; 5] = [
    "aws_access_key_id",
    "aws_secret_access_key",
    "aws_session_token",
    "region",
    "endpoint_url",
];

/// The profile's settings from both files (credentials first, as the AWS tools read them);
/// missing or unreadable files give nothing.
pub fn profile_settings() -> HashMap<String, String> {
    let profile = std::env::var("AWS_PROFILE").unwrap_or_else(|_| "default".into());
    let home = std::env::var_os("HOME").map(PathBuf::from);
    let file = |var: &str, name: &str| {
        std::env::var_os(var)
            .map(PathBuf::from)
            .or_else(|| home.as_ref().map(|h| h.join(".aws").join(name)))
    };
    let mut settings = HashMap::new();
    // The config file names profiles `[profile NAME]`, except `[default]`.
    let sources = [
        (file("AWS_SHARED_CREDENTIALS_FILE", "credentials"), false),
        (file("AWS_CONFIG_FILE", "config"), true),
    ];
    for (path, is_config) in sources {
        let Some(text) = path.and_then(|p| std::fs::read_to_string(p).ok()) else {
            continue;
        };
        for (key, value) in section(&text, &profile, is_config) {
            settings.entry(key).or_insert(value);
        }
    }
    settings
}

/// The `key = value` lines of one profile's section of an INI-style AWS file.
pub fn section(text: &str, profile: &str, is_config: bool) -> Vec<(String, String)> {
    let wanted = if is_config && profile != "default" {
        format!("profile {profile}")
    } else {
        profile.to_string()
    };
    let mut inside = false;
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
            continue;
        }
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            inside = name.split_whitespace().collect::<Vec<_>>().join(" ") == wanted;
            continue;
        }
        if !inside {
            continue;
        }
        if let Some((key, value)) = line.split_once('=') {
            let key = key.trim().to_ascii_lowercase();
            if KEYS.contains(&key.as_str()) {
                out.push((key, value.trim().to_string()));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const CONFIG: &str = "# comment\n[default]\nregion = eu-west-1\n\n[profile survey]\nregion=us-east-2\nendpoint_url = http://127.0.0.1:9000\noutput = json\n";

    #[test]
    fn config_profiles_are_named_with_the_profile_prefix() {
        assert_eq!(
            section(CONFIG, "default", true),
            vec![("region".into(), "eu-west-1".into())]
        );
        assert_eq!(
            section(CONFIG, "survey", true),
            vec![
                ("region".into(), "us-east-2".into()),
                ("endpoint_url".into(), "http://127.0.0.1:9000".into())
            ]
        );
        assert!(section(CONFIG, "missing", true).is_empty());
    }

    #[test]
    fn credentials_profiles_are_bare_names() {
        let creds = "[survey]\naws_access_key_id = AKIA\naws_secret_access_key = s3cr=t\n";
        assert_eq!(
            section(creds, "survey", false),
            vec![
                ("aws_access_key_id".into(), "AKIA".into()),
                ("aws_secret_access_key".into(), "s3cr=t".into())
            ]
        );
        assert!(section(creds, "survey", true).is_empty());
    }
}
