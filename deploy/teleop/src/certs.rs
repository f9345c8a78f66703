//! `teleop certs`: a certificate authority and the certificates of a deployment's
//! identities for mutual TLS between the sites (teleop_node::certs).

use std::path::PathBuf;

use anyhow::Context;
use teleop_interfaces::nodes::NODES;
use teleop_node::certs::{self, Identity};

#[derive(Debug, Clone, clap::Args)]
pub struct CertsArgs {
    /// Directory of the authority (ca.pem, ca.key) and the identities (NAME.pem,
    /// NAME.key); an authority already there signs the new certificates.
    #[arg(long)]
    pub out: PathBuf,
    /// Identities to certify, `NAME` or `NAME=SAN,SAN,...` (DNS names or IP addresses
    /// it is reached at). Default: every node of the node table, `local-router`,
    /// `remote-router` and `teleop-observer`.
    pub identities: Vec<String>,
    /// Validity in days.
    #[arg(long, default_value_t = 365)]
    pub days: u32,
    /// Keep identities whose certificate and key are already in --out.
    #[arg(long)]
    pub keep_existing: bool,
}

/// The identities of a deployment: every node, both routers, one observer.
pub fn deployment_identities() -> Vec<String> {
    let mut out: Vec<String> = NODES.iter().map(|n| n.name.to_owned()).collect();
    use teleop_node::access::SiteName;
    out.extend([SiteName::Local, SiteName::Remote].map(|s| s.router_name().to_owned()));
    out.push("teleop-observer".to_owned());
    out
}

pub fn run(args: CertsArgs) -> anyhow::Result<()> {
    let names = if args.identities.is_empty() {
        deployment_identities()
    } else {
        args.identities.clone()
    };
    let ids = names
        .iter()
        .map(|s| s.parse::<Identity>())
        .collect::<Result<Vec<_>, _>>()?;
    let issued = certs::issue(&args.out, &ids, args.days, args.keep_existing)
        .with_context(|| format!("making certificates in {}", args.out.display()))?;
    let dir = args.out.display();
    if issued.new_authority {
        println!(
            "new certificate authority: {dir}/ca.pem (its key {dir}/ca.key signs; keep it off the robots)"
        );
    } else {
        println!("certificate authority: {dir}/ca.pem (reused)");
    }
    for name in &issued.written {
        println!("issued {dir}/{name}.pem + {name}.key ({} days)", args.days);
    }
    for name in &issued.kept {
        println!("kept   {dir}/{name}.pem");
    }
    Ok(())
}
