//! `towernav-fleet`: the fleet's certificate authority on the command line.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use towernav_fleet::{Authority, node};
use towernav_protocol::security::{Credentials, Role};

const ROTATION: &str = "\
Rotating:
  a node's certificate:  `towernav-fleet issue` again with the same --name
                         (same role); copy its nodes/<name>/ folder to it and
                         restart it. The old certificate is superseded: it loses
                         its rights once the others have the new roster.
  the CA:                `towernav-fleet rotate-ca` makes a new CA and issues
                         every node on the roster again; hand out the whole
                         nodes/ tree and restart every node.
  taking a node out:     `towernav-fleet revoke --name N`, then hand out the
                         nodes/ tree (every node's roster): the others deny its
                         certificate everything, for good (the rules name
                         certificates by serial, and a serial is never named
                         again). It still completes a TLS handshake until it
                         expires or the CA is rotated, and gets nothing.";

/// The fleet's own certificate authority: certificates for mutual TLS between
/// edges, ground stations and routers, and the roster every node builds its
/// access rules from. Keep the CA folder (and its ca.key) at the ground.
#[derive(Parser)]
#[command(name = "towernav-fleet", after_long_help = ROTATION)]
struct Cli {
    /// The CA folder (ca.pem, ca.key, roster.toml, nodes/).
    #[arg(long, default_value = "fleet")]
    dir: PathBuf,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Creates the fleet's CA and an empty roster.
    Init {
        /// The fleet id, as the nodes' `fleet` setting.
        #[arg(long)]
        fleet: String,
        /// How long the CA is valid.
        #[arg(long, default_value_t = 3650)]
        days: i64,
    },
    /// Issues (or issues again) one node's certificate into nodes/<name>/.
    Issue {
        /// The node's certificate name.
        #[arg(long)]
        name: String,
        #[arg(long, value_enum)]
        role: RoleArg,
        /// An edge's UAV id.
        #[arg(long)]
        uav: Option<String>,
        /// A host name or IP address other nodes reach it by (repeatable);
        /// they check it when they connect to the node.
        #[arg(long = "host")]
        hosts: Vec<String>,
        #[arg(long, default_value_t = 365)]
        days: i64,
    },
    /// Takes a node off the roster and deletes its folder.
    Revoke {
        #[arg(long)]
        name: String,
    },
    /// A new CA, and every node on the roster issued again under it.
    RotateCa {
        #[arg(long, default_value_t = 3650)]
        days: i64,
        #[arg(long, default_value_t = 365)]
        node_days: i64,
    },
    /// Writes a zenohd config for a router node (issued with --role router).
    RouterConfig {
        #[arg(long)]
        name: String,
        /// Where the router listens (repeatable), e.g. tls/0.0.0.0:7447.
        #[arg(long, required = true)]
        listen: Vec<String>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Lists each node's current certificate (serial, fingerprint, expiry)
    /// and the retired ones.
    List,
    /// Prints the roster file.
    Show,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum RoleArg {
    GroundStation,
    Edge,
    Router,
}

impl From<RoleArg> for Role {
    fn from(r: RoleArg) -> Self {
        match r {
            RoleArg::GroundStation => Role::GroundStation,
            RoleArg::Edge => Role::Edge,
            RoleArg::Router => Role::Router,
        }
    }
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let dir = &cli.dir;
    match cli.command {
        Command::Init { fleet, days } => {
            Authority::init(dir, &fleet, days)?;
            println!(
                "fleet {fleet}: CA in {}; keep ca.key there, off the vehicles",
                dir.display()
            );
        }
        Command::Issue {
            name,
            role,
            uav,
            hosts,
            days,
        } => {
            let mut authority = Authority::open(dir)?;
            let node = node(&name, role.into(), uav.as_deref(), &hosts)?;
            let out = authority.issue(node, days)?;
            println!(
                "{name}: {} (copy it to the node; the other nodes' rosters in {} changed too)",
                out.display(),
                dir.join(towernav_fleet::NODES_DIR).display()
            );
        }
        Command::Revoke { name } => {
            Authority::open(dir)?.revoke(&name)?;
            println!("{name} revoked: hand out the nodes/ tree again");
        }
        Command::RotateCa { days, node_days } => {
            let mut authority = Authority::open(dir)?;
            authority.rotate_ca(days, node_days)?;
            println!(
                "new CA; {} nodes issued again: hand out the nodes/ tree and restart every node",
                authority.roster().nodes.len()
            );
        }
        Command::RouterConfig { name, listen, out } => {
            let authority = Authority::open(dir)?;
            let credentials = Credentials::load(&authority.node_dir(&name), &name)?;
            if authority.roster().node(&name).map(|n| n.role) != Some(Role::Router) {
                anyhow::bail!("{name} is not a router on the roster (issue it with --role router)");
            }
            let config = towernav_fleet::router::router_config(&credentials, &listen);
            let text = serde_json::to_string_pretty(&config)?;
            std::fs::write(&out, text).with_context(|| format!("writing {}", out.display()))?;
            println!("zenohd -c {}", out.display());
        }
        Command::List => {
            print!(
                "{}",
                towernav_fleet::listing(Authority::open(dir)?.roster())
            );
        }
        Command::Show => {
            let authority = Authority::open(dir)?;
            print!("{}", authority.roster().to_toml());
        }
    }
    Ok(())
}
