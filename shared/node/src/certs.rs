//! Certificates for mutual TLS between the sites (`teleop certs`): a certificate
//! authority and one certificate per identity, each with the identity as its common
//! name (what a router's access control knows the peer by) and the names and addresses
//! it is reached at as subject alternative names (what a connecting peer checks).
//!
//! This is the throwaway kind a test or a lab makes for itself; docs/security.md says
//! how to make and keep real ones.

use std::path::{Path, PathBuf};

use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};

/// Why certificates could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CertError {
    #[error("identity `{0}`: a common name must be non-empty, without blanks or `/`")]
    BadName(String),
    #[error("identity `{name}`: subject alternative name `{san}`: {message}")]
    BadSan {
        name: String,
        san: String,
        message: String,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    BadFile { path: PathBuf, message: String },
    #[error("certificate generation: {0}")]
    Generate(String),
}

/// One identity to certify: its common name and where it is reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// Common name: a node's name, a router's name, an observer's name.
    pub name: String,
    /// Subject alternative names besides `name` itself: DNS names or IP addresses.
    pub sans: Vec<String>,
}

impl std::str::FromStr for Identity {
    type Err = CertError;

    /// `NAME` or `NAME=SAN,SAN,...` (e.g. `remote-router=172.30.2.2,remote-site.wan`).
    fn from_str(s: &str) -> Result<Self, CertError> {
        let (name, sans) = s.split_once('=').unwrap_or((s, ""));
        check_name(name)?;
        let sans = sans
            .split(',')
            .map(str::trim)
            .filter(|x| !x.is_empty())
            .map(str::to_owned)
            .collect();
        Ok(Self {
            name: name.to_owned(),
            sans,
        })
    }
}

fn check_name(name: &str) -> Result<(), CertError> {
    if name.is_empty()
        || name
            .chars()
            .any(|c| c.is_whitespace() || c == '/' || c == '=')
    {
        return Err(CertError::BadName(name.to_owned()));
    }
    Ok(())
}

/// File names in a certificate directory.
pub const CA_CERT: &str = "ca.pem";
/// The authority's private key.
pub const CA_KEY: &str = "ca.key";

/// Paths of `name`'s certificate and key in `dir`.
pub fn identity_files(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("{name}.pem")),
        dir.join(format!("{name}.key")),
    )
}

/// What [`issue`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Issued {
    /// Whether a new authority was made (else the one in the directory signed).
    pub new_authority: bool,
    /// Identities certified now.
    pub written: Vec<String>,
    /// Identities whose files were there already and were kept (`keep_existing`).
    pub kept: Vec<String>,
}

/// Makes (or reuses) the authority in `dir` and a certificate + key per identity,
/// valid for `days` from now. With `keep_existing`, identities that already have both
/// files are left alone.
///
/// # Errors
/// [`CertError`] naming the identity or file at fault.
pub fn issue(
    dir: &Path,
    identities: &[Identity],
    days: u32,
    keep_existing: bool,
) -> Result<Issued, CertError> {
    for id in identities {
        check_name(&id.name)?;
    }
    std::fs::create_dir_all(dir).map_err(|source| CertError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let gen_err = |e: rcgen::Error| CertError::Generate(e.to_string());
    let (ca_cert_path, ca_key_path) = (dir.join(CA_CERT), dir.join(CA_KEY));
    let new_authority = !ca_cert_path.exists();
    let (ca_cert_pem, ca_key) = if new_authority {
        let key = KeyPair::generate().map_err(gen_err)?;
        let mut params = CertificateParams::new(Vec::<String>::new()).map_err(gen_err)?;
        params
            .distinguished_name
            .push(DnType::CommonName, "teleop deployment CA");
        params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
        params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        set_validity(&mut params, days);
        let cert = params.self_signed(&key).map_err(gen_err)?;
        write(&ca_key_path, &key.serialize_pem(), true)?;
        write(&ca_cert_path, &cert.pem(), false)?;
        (cert.pem(), key)
    } else {
        let cert = read(&ca_cert_path)?;
        let key_pem = read(&ca_key_path)?;
        let key = KeyPair::from_pem(&key_pem).map_err(|e| CertError::BadFile {
            path: ca_key_path.clone(),
            message: e.to_string(),
        })?;
        (cert, key)
    };
    let issuer =
        Issuer::from_ca_cert_pem(&ca_cert_pem, ca_key).map_err(|e| CertError::BadFile {
            path: ca_cert_path.clone(),
            message: e.to_string(),
        })?;

    let mut out = Issued {
        new_authority,
        written: Vec::new(),
        kept: Vec::new(),
    };
    for id in identities {
        let (cert_path, key_path) = identity_files(dir, &id.name);
        if keep_existing && !new_authority && cert_path.exists() && key_path.exists() {
            out.kept.push(id.name.clone());
            continue;
        }
        let mut names = vec![id.name.clone()];
        names.extend(id.sans.iter().cloned());
        let mut params = CertificateParams::new(names).map_err(|e| CertError::BadSan {
            name: id.name.clone(),
            san: id.sans.join(","),
            message: e.to_string(),
        })?;
        params.distinguished_name.push(DnType::CommonName, &id.name);
        params.key_usages = vec![
            KeyUsagePurpose::DigitalSignature,
            KeyUsagePurpose::KeyEncipherment,
        ];
        // Every process is a server (it listens) and a client (it connects).
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        set_validity(&mut params, days);
        let key = KeyPair::generate().map_err(gen_err)?;
        let cert = params.signed_by(&key, &issuer).map_err(gen_err)?;
        write(&key_path, &key.serialize_pem(), true)?;
        write(&cert_path, &cert.pem(), false)?;
        out.written.push(id.name.clone());
    }
    Ok(out)
}

fn set_validity(params: &mut CertificateParams, days: u32) {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let now = time::OffsetDateTime::UNIX_EPOCH + time::Duration::seconds(now as i64);
    // An hour of slack for clocks that disagree a little.
    params.not_before = now - time::Duration::hours(1);
    params.not_after = now + time::Duration::days(i64::from(days));
}

fn read(path: &Path) -> Result<String, CertError> {
    std::fs::read_to_string(path).map_err(|source| CertError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Writes `text`; private keys readable by their owner only.
fn write(path: &Path, text: &str, private: bool) -> Result<(), CertError> {
    let io = |source| CertError::Io {
        path: path.to_owned(),
        source,
    };
    std::fs::write(path, text).map_err(io)?;
    #[cfg(unix)]
    if private {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).map_err(io)?;
    }
    #[cfg(not(unix))]
    let _ = private;
    Ok(())
}

/// The TLS settings of identity `name` whose files are in `dir`.
pub fn tls_settings(dir: &Path, name: &str) -> teleop_bus::TlsSettings {
    let (certificate, private_key) = identity_files(dir, name);
    teleop_bus::TlsSettings {
        ca_certificate: dir.join(CA_CERT),
        certificate,
        private_key,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identities_parse_and_bad_names_are_named() {
        let id: Identity = "remote-router=172.30.2.2, remote-site.wan".parse().unwrap();
        assert_eq!(id.name, "remote-router");
        assert_eq!(id.sans, ["172.30.2.2", "remote-site.wan"]);
        for bad in ["", "a b", "x/y"] {
            let e = bad.parse::<Identity>().unwrap_err();
            assert!(matches!(e, CertError::BadName(_)), "{bad}: {e}");
        }
    }

    #[test]
    fn issues_a_ca_and_identities_then_reuses_the_ca() {
        let dir = std::env::temp_dir().join(format!("teleop-certs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let ids: Vec<Identity> = ["wrist_tracker", "local-router=127.0.0.1"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        let first = issue(&dir, &ids, 30, true).unwrap();
        assert!(first.new_authority);
        assert_eq!(first.written, ["wrist_tracker", "local-router"]);
        let ca = std::fs::read_to_string(dir.join(CA_CERT)).unwrap();
        assert!(ca.starts_with("-----BEGIN CERTIFICATE-----"));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(dir.join("wrist_tracker.key"))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        // Again: the same authority, existing identities kept, a new one signed.
        let more: Vec<Identity> = ["wrist_tracker", "teleop-observer"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        let second = issue(&dir, &more, 30, true).unwrap();
        assert!(!second.new_authority);
        assert_eq!(second.kept, ["wrist_tracker"]);
        assert_eq!(second.written, ["teleop-observer"]);
        assert_eq!(std::fs::read_to_string(dir.join(CA_CERT)).unwrap(), ca);
        // A bad SAN is named.
        let bad = Identity {
            name: "x".into(),
            sans: vec!["näme".into()],
        };
        let e = issue(&dir, &[bad], 30, false).unwrap_err();
        assert!(e.to_string().contains("näme"), "{e}");
        // The files make a valid TLS setting for the bus.
        let s = teleop_bus::ZenohSettings {
            listen: vec!["tls/127.0.0.1:0".into()],
            tls: Some(tls_settings(&dir, "wrist_tracker")),
            ..Default::default()
        };
        s.to_zenoh().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
