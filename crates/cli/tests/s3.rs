//! Stores read from `s3://`: an S3-compatible server (moto's, installed by
//! `scripts/ensure-moto.sh`) started by the test on loopback, the store uploaded to it, and
//! `info` and `render` of `s3://BUCKET/KEY` compared with the same commands on the local file:
//! the images are identical. Credentials and the endpoint come from the environment or from the
//! AWS profile files; missing objects and buckets are clear errors.

mod common;
use common::*;
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The Python of the virtual environment `scripts/ensure-moto.sh` makes.
fn moto_python() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/tools/moto/bin/python3");
    assert!(
        p.exists(),
        "the S3 test server is not installed ({}): run `bash scripts/ensure-moto.sh` \
         (scripts/test.sh does)",
        p.display()
    );
    p
}

/// A moto S3 server on a free loopback port, stopped when dropped.
struct S3Server {
    child: Child,
    endpoint: String,
}

impl S3Server {
    fn start() -> S3Server {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free loopback port")
            .port();
        let child = Command::new(moto_python())
            .args([
                "-m",
                "moto.server",
                "-H",
                "127.0.0.1",
                "-p",
                &port.to_string(),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("starting moto's S3 server");
        let server = S3Server {
            child,
            endpoint: format!("http://127.0.0.1:{port}"),
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                Instant::now() < deadline,
                "moto's S3 server did not listen on port {port} within 60 s"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        server
    }

    /// Creates `bucket` and uploads `file` as `key`, with boto3 (moto's dependency).
    fn upload(&self, bucket: &str, key: &str, file: &Path) {
        let script = "import boto3, sys\n\
             s3 = boto3.client('s3', endpoint_url=sys.argv[1], region_name='us-east-1',\n\
             aws_access_key_id='testing', aws_secret_access_key='testing')\n\
             s3.create_bucket(Bucket=sys.argv[2])\n\
             s3.upload_file(sys.argv[4], sys.argv[2], sys.argv[3])\n";
        let out = Command::new(moto_python())
            .args(["-c", script, &self.endpoint, bucket, key, s(file)])
            .output()
            .expect("running the upload script");
        assert!(
            out.status.success(),
            "uploading to the S3 test server failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

impl Drop for S3Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `pointlet args` with only `env` for AWS settings (none inherited from the machine).
fn pointlet_with(env: &[(&str, &str)], args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_pointlet"));
    for (k, _) in std::env::vars() {
        if k.starts_with("AWS_") {
            cmd.env_remove(k);
        }
    }
    cmd.envs(env.iter().copied())
        .env(
            "HOME",
            std::env::temp_dir().join("pointlet-s3-test-no-home"),
        )
        .env("POINTLET_REMOTE_TIMEOUT_MS", "10000")
        .args(args)
        .output()
        .expect("running the pointlet binary")
}

fn succeeded(out: &Output, what: &str) -> String {
    assert!(
        out.status.success(),
        "{what} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn a_store_in_s3_renders_exactly_like_the_local_store() {
    let server = S3Server::start();
    let dir = tempfile::tempdir().expect("temp dir");
    let store = dir.path().join("autzen.pointlet");
    ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&store)]);
    server.upload("surveys", "oregon/autzen.pointlet", &store);
    let env = [
        ("AWS_ENDPOINT_URL", server.endpoint.as_str()),
        ("AWS_ACCESS_KEY_ID", "testing"),
        ("AWS_SECRET_ACCESS_KEY", "testing"),
        ("AWS_REGION", "us-east-1"),
    ];
    let url = "s3://surveys/oregon/autzen.pointlet";

    let local_info = ok(&["info", s(&store)]);
    let remote_info = succeeded(&pointlet_with(&env, &["info", url]), "info over s3");
    // The same header, points and bounds; only the location line differs.
    let body = |text: &str| -> Vec<String> {
        text.lines()
            .filter(|l| !l.contains("autzen.pointlet"))
            .map(str::to_string)
            .collect()
    };
    assert_eq!(body(&local_info), body(&remote_info));

    let camera = ["--width", "320", "--height", "240", "--view", "closeup"];
    for extra in [
        &["--point-size", "1"][..],
        &["--point-size", "adaptive", "--edl"],
    ] {
        let local_png = dir.path().join("local.png");
        let remote_png = dir.path().join("remote.png");
        let mut args = vec!["render", s(&store), "-o", s(&local_png)];
        args.extend(camera);
        args.extend(extra);
        ok(&args);
        args[1] = url;
        args[3] = s(&remote_png);
        succeeded(&pointlet_with(&env, &args), "render over s3");
        let (a, b) = (png_rgba(&local_png), png_rgba(&remote_png));
        assert!(a.iter().any(|v| *v != 0), "the local render is empty");
        assert!(a == b, "s3 render differs from the local one ({extra:?})");
    }

    // The endpoint and keys from the profile files instead of the environment.
    let aws = dir.path().join("aws");
    std::fs::create_dir_all(&aws).expect("aws dir");
    std::fs::write(
        aws.join("credentials"),
        "[survey]\naws_access_key_id = testing\naws_secret_access_key = testing\n",
    )
    .expect("credentials file");
    std::fs::write(
        aws.join("config"),
        format!(
            "[profile survey]\nregion = us-east-1\nendpoint_url = {}\n",
            server.endpoint
        ),
    )
    .expect("config file");
    let creds = aws.join("credentials");
    let config = aws.join("config");
    let profile_env = [
        ("AWS_PROFILE", "survey"),
        ("AWS_SHARED_CREDENTIALS_FILE", s(&creds)),
        ("AWS_CONFIG_FILE", s(&config)),
    ];
    let from_files = succeeded(
        &pointlet_with(&profile_env, &["info", url]),
        "info with profile files",
    );
    assert_eq!(body(&local_info), body(&from_files));

    // Missing objects and buckets name what is missing and fail cleanly.
    for missing in [
        "s3://surveys/oregon/nothing.pointlet",
        "s3://no-such-bucket/autzen.pointlet",
    ] {
        let out = pointlet_with(&env, &["info", missing]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "info {missing}:\n{err}");
        assert!(!err.contains("panicked"), "info {missing} panicked:\n{err}");
        assert!(
            err.contains(missing) && err.to_lowercase().contains("not found"),
            "info {missing}: the message should name the store and say it is not found:\n{err}"
        );
    }
}
