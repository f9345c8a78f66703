//! Who may do what through a site's router: the Zenoh access control a router enforces,
//! generated from the topic table (who publishes each topic, which way it crosses) and
//! the node table (which site each node is on), for peers known by the common name of
//! their TLS certificate.
//!
//! With access control on, a router lets through only what the tables say, and nothing
//! from a peer it does not know (default deny):
//!
//! * a node of its own site (certificate common name = the node's name) publishes only
//!   the topics the table names it as a publisher of, announces liveliness only under
//!   its own name, and may subscribe to anything; hardware topics (`teleop/hw/...`) only
//!   over the site's hardware interfaces;
//! * the other site's router (a `peer_routers` name) brings in only the topics that
//!   cross toward this site (and node status), and the liveliness of the other site's
//!   nodes; it is sent only the topics that cross away from this site, never a
//!   hardware topic;
//! * an observer (monitor, recorder, `teleop report`: an `observers` name) may
//!   subscribe and announce itself (as `teleop_...`), never publish;
//! * anybody else, even with a certificate of the same authority: nothing at all.

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use teleop_interfaces::nodes::{NODES, Site};
use teleop_interfaces::topics::{self, Direction, TopicSpec};

/// Which site a router serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SiteName {
    Local,
    Remote,
}

impl SiteName {
    /// The other site.
    pub fn other(self) -> Self {
        match self {
            SiteName::Local => SiteName::Remote,
            SiteName::Remote => SiteName::Local,
        }
    }
    /// The conventional identity of the site's router (`local-router`,
    /// `remote-router`): what the deployment's certificates and configs call it.
    pub fn router_name(self) -> &'static str {
        match self {
            SiteName::Local => "local-router",
            SiteName::Remote => "remote-router",
        }
    }
}

impl From<SiteName> for Site {
    fn from(s: SiteName) -> Self {
        match s {
            SiteName::Local => Site::Local,
            SiteName::Remote => Site::Remote,
        }
    }
}

/// A router's `[access]` section.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccessConfig {
    /// Enforce the tables (needs `bus.zenoh.tls`: peers are known by their
    /// certificates). Off by default: a router without TLS lets every peer through
    /// (hardware topics are still kept on the site's interfaces).
    pub enabled: bool,
    /// The site this router serves; its nodes are the node table's nodes of this site.
    pub site: SiteName,
    /// Certificate common names of the other site's routers.
    pub peer_routers: Vec<String>,
    /// Certificate common names of tools that may watch but not publish.
    pub observers: Vec<String>,
}

impl Default for AccessConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            site: SiteName::Local,
            peer_routers: Vec::new(),
            observers: Vec::new(),
        }
    }
}

/// Bus name prefix of the `teleop` tools (`teleop_cli_<pid>`, `teleop_report_<pid>`):
/// the liveliness an observer may announce.
pub const OBSERVER_NODE_PREFIX: &str = "teleop_";

/// Every message kind Zenoh's access control knows.
const ALL_MESSAGES: [&str; 9] = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
];
/// Where a peer may watch: every key; `**` does not match chunks that start with `@`
/// (Zenoh's verbatim chunks), so the graph's liveliness keys are named as well.
fn watch_keys() -> Vec<String> {
    vec![
        "**".into(),
        format!("{}/**", teleop_bus::keys::LIVELINESS_PREFIX),
    ]
}

/// What a peer needs to send to watch: subscriptions and the graph.
const WATCH_MESSAGES: [&str; 3] = [
    "declare_subscriber",
    "declare_liveliness_subscriber",
    "liveliness_query",
];

impl AccessConfig {
    /// Checks the names.
    ///
    /// # Errors
    /// A text naming the offending entry.
    pub fn validate(&self) -> Result<(), String> {
        let site: Site = self.site.into();
        let nodes: Vec<&str> = site_nodes(site).collect();
        let mut seen: Vec<&str> = nodes.clone();
        for (field, names) in [
            ("peer_routers", &self.peer_routers),
            ("observers", &self.observers),
        ] {
            for name in names {
                if name.is_empty() || name.chars().any(|c| c.is_whitespace() || c == '/') {
                    return Err(format!(
                        "access.{field}: `{name}` is not a certificate common name (empty, blank or with `/`)"
                    ));
                }
                if seen.contains(&name.as_str()) {
                    return Err(format!(
                        "access.{field}: `{name}` is named twice (or is a node of this site): one identity, one role"
                    ));
                }
                seen.push(name);
            }
        }
        Ok(())
    }

    /// The Zenoh `access_control` block for this router. `hardware_interfaces` are the
    /// host's interfaces on which hardware topics may travel (already resolved from
    /// subnets; `*` for any).
    pub fn zenoh_acl(&self, hardware_interfaces: &[String]) -> Value {
        let site: Site = self.site.into();
        let mut acl = Acl::default();
        let any_interface = hardware_interfaces.iter().any(|i| i == "*");

        // The nodes of this site.
        for node in site_nodes(site) {
            let published: Vec<&TopicSpec> = topics::ALL
                .iter()
                .filter(|t| t.publishers.includes(node))
                .collect();
            let (hw, data): (Vec<&TopicSpec>, Vec<&TopicSpec>) = published
                .into_iter()
                .partition(|t| topics::is_hardware_topic(t.name));
            let rules = vec![
                acl.rule("ingress", &["put"], data_keys(&data)),
                acl.rule("ingress", &["liveliness_token"], token_keys(node)),
                acl.rule("ingress", &WATCH_MESSAGES, watch_keys()),
                acl.rule("egress", &ALL_MESSAGES, non_hardware_keys()),
            ];
            acl.policy(&format!("node {node}"), node, None, rules);
            // Hardware topics: only over the site's hardware interfaces.
            let interfaces = (!any_interface).then_some(hardware_interfaces);
            let rules = vec![
                acl.rule("ingress", &["put"], data_keys(&hw)),
                acl.rule("egress", &ALL_MESSAGES, vec![HARDWARE_KEYS.into()]),
            ];
            acl.policy(&format!("node {node} hardware"), node, interfaces, rules);
        }

        // The other site's routers: the crossing topics, each way.
        let (inbound, outbound) = match site {
            Site::Local => (Direction::RemoteToLocal, Direction::LocalToRemote),
            Site::Remote => (Direction::LocalToRemote, Direction::RemoteToLocal),
        };
        let crossing = |d: Direction| -> Vec<&'static TopicSpec> {
            topics::ALL
                .iter()
                .filter(|t| t.direction == d || t.direction == Direction::Both)
                .collect()
        };
        let other = match site {
            Site::Local => Site::Remote,
            Site::Remote => Site::Local,
        };
        let other_tokens: Vec<String> = site_nodes(other).flat_map(token_keys).collect();
        let own_tokens: Vec<String> = site_nodes(site).flat_map(token_keys).collect();
        for peer in &self.peer_routers {
            let rules = vec![
                acl.rule("ingress", &["put"], data_keys(&crossing(inbound))),
                acl.rule("ingress", &["liveliness_token"], other_tokens.clone()),
                acl.rule("ingress", &WATCH_MESSAGES, watch_keys()),
                acl.rule("egress", &["put"], data_keys(&crossing(outbound))),
                acl.rule("egress", &["liveliness_token"], own_tokens.clone()),
                acl.rule("egress", &WATCH_MESSAGES, watch_keys()),
                acl.rule("egress", &["reply"], watch_keys()),
            ];
            acl.policy(&format!("peer router {peer}"), peer, None, rules);
        }

        // Observers: watch everything of the site, publish nothing.
        for observer in &self.observers {
            let rules = vec![
                acl.rule(
                    "ingress",
                    &["liveliness_token"],
                    token_keys(&format!("{OBSERVER_NODE_PREFIX}$*")),
                ),
                acl.rule("ingress", &WATCH_MESSAGES, watch_keys()),
                acl.rule("egress", &ALL_MESSAGES, non_hardware_keys()),
                // The routers' admin space (links, sessions, routes): observers alone.
                acl.rule("ingress", &["query"], vec![ADMIN_SPACE.into()]),
                acl.rule("egress", &["reply"], vec![ADMIN_SPACE.into()]),
            ];
            acl.policy(&format!("observer {observer}"), observer, None, rules);
            let interfaces = (!any_interface).then_some(hardware_interfaces);
            let rule = acl.rule("egress", &ALL_MESSAGES, vec![HARDWARE_KEYS.into()]);
            acl.policy(
                &format!("observer {observer} hardware"),
                observer,
                interfaces,
                vec![rule],
            );
        }
        acl.finish()
    }
}

/// Zenoh's admin space (`@/<zid>/router/...` of a router that enables it).
pub const ADMIN_SPACE: &str = "@/**";

/// Key expression of every hardware topic's data, in any domain.
const HARDWARE_KEYS: &str = teleop_bus::config::HARDWARE_KEYS;

/// The node table's nodes of `site`.
pub fn site_nodes(site: Site) -> impl Iterator<Item = &'static str> {
    NODES.iter().filter(move |n| n.site == site).map(|n| n.name)
}

/// Data keys of `topics` in any domain: `*/<topic>/<type>/<hash>`.
fn data_keys(topics: &[&TopicSpec]) -> Vec<String> {
    topics.iter().map(|t| format!("*/{}/*/*", t.name)).collect()
}

/// Every key but the hardware topics' data: the data keys of every other topic, plus
/// everything that is not a data key of the teleop topics (liveliness, the graph).
fn non_hardware_keys() -> Vec<String> {
    let mut keys: Vec<String> = topics::ALL
        .iter()
        .filter(|t| !topics::is_hardware_topic(t.name))
        .map(|t| format!("*/{}/*/*", t.name))
        .collect();
    keys.push(format!("{}/**", teleop_bus::keys::LIVELINESS_PREFIX));
    keys
}

/// The liveliness keys a node called `node` announces (its own token and those of its
/// publishers and subscribers): `@ros2_lv/<domain>/<zid>/<nid>/<eid>/<kind>/<enclave>/
/// <namespace>/<node>[/...]`.
fn token_keys(node: &str) -> Vec<String> {
    let base = format!(
        "{}/*/*/*/*/*/*/*/{node}",
        teleop_bus::keys::LIVELINESS_PREFIX
    );
    vec![base.clone(), format!("{base}/**")]
}

/// A Zenoh access-control block under construction.
#[derive(Debug, Default)]
struct Acl {
    rules: Vec<Value>,
    subjects: Vec<Value>,
    policies: Vec<Value>,
}

impl Acl {
    /// An allow rule; `None` when it names no key (nothing to allow).
    fn rule(&mut self, flow: &str, messages: &[&str], keys: Vec<String>) -> Option<String> {
        if keys.is_empty() {
            return None;
        }
        let id = format!("r{}", self.rules.len());
        self.rules.push(json!({
            "id": id,
            "permission": "allow",
            "flows": [flow],
            "messages": messages,
            "key_exprs": keys,
        }));
        Some(id)
    }

    /// A subject (certificate common name, on `interfaces` if given) with its rules.
    fn policy(
        &mut self,
        id: &str,
        common_name: &str,
        interfaces: Option<&[String]>,
        rules: Vec<Option<String>>,
    ) {
        let rules: Vec<String> = rules.into_iter().flatten().collect();
        if rules.is_empty() {
            return;
        }
        let mut subject = json!({ "id": id, "cert_common_names": [common_name] });
        if let Some(ifaces) = interfaces {
            subject["interfaces"] = json!(ifaces);
        }
        self.subjects.push(subject);
        self.policies
            .push(json!({ "rules": rules, "subjects": [id] }));
    }

    fn finish(self) -> Value {
        json!({
            "enabled": true,
            "default_permission": "deny",
            "rules": self.rules,
            "subjects": self.subjects,
            "policies": self.policies,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(site: SiteName) -> AccessConfig {
        AccessConfig {
            enabled: true,
            site,
            peer_routers: vec![site.other().router_name().into()],
            observers: vec!["teleop-observer".into()],
        }
    }

    /// The keys the policy of subject `id` allows for `flow` and `message`.
    fn allowed(acl: &Value, id: &str, flow: &str, message: &str) -> Vec<String> {
        let Some(policy) = acl["policies"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["subjects"][0] == id)
        else {
            return Vec::new();
        };
        let mut out = Vec::new();
        for rule_id in policy["rules"].as_array().unwrap() {
            let rule = acl["rules"]
                .as_array()
                .unwrap()
                .iter()
                .find(|r| &r["id"] == rule_id)
                .unwrap();
            let has = |field: &str, v: &str| {
                rule[field]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|x| x.as_str() == Some(v))
            };
            if has("flows", flow) && has("messages", message) {
                for k in rule["key_exprs"].as_array().unwrap() {
                    out.push(k.as_str().unwrap().to_owned());
                }
            }
        }
        out
    }

    #[test]
    fn each_node_publishes_only_its_topics_and_hardware_only_on_site_interfaces() {
        let hw = vec!["lo".to_owned(), "eth1".to_owned()];
        let acl = cfg(SiteName::Remote).zenoh_acl(&hw);
        assert_eq!(acl["default_permission"], "deny");
        let arm = allowed(&acl, "node pr2_arm_controller", "ingress", "put");
        assert!(arm.contains(&"*/teleop/status/*/*".to_owned()), "{arm:?}");
        assert!(!arm.iter().any(|k| k.contains("hw/")), "{arm:?}");
        let arm_hw = allowed(&acl, "node pr2_arm_controller hardware", "ingress", "put");
        assert_eq!(arm_hw, ["*/teleop/hw/pr2_arm/command/*/*"]);
        // The hardware subject is bound to the site's interfaces.
        let subject = acl["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["id"] == "node pr2_arm_controller hardware")
            .unwrap();
        assert_eq!(subject["interfaces"], json!(["lo", "eth1"]));
        assert_eq!(subject["cert_common_names"], json!(["pr2_arm_controller"]));
        // The simulator publishes the robots' states, never a command.
        let sim_hw = allowed(&acl, "node remote_sim hardware", "ingress", "put");
        assert!(sim_hw.contains(&"*/teleop/hw/pr2_arm/state/*/*".to_owned()));
        assert!(!sim_hw.iter().any(|k| k.contains("command")), "{sim_hw:?}");
        // Liveliness only under one's own name.
        let tokens = allowed(
            &acl,
            "node feedback_publisher",
            "ingress",
            "liveliness_token",
        );
        assert_eq!(
            tokens,
            [
                "@ros2_lv/*/*/*/*/*/*/*/feedback_publisher",
                "@ros2_lv/*/*/*/*/*/*/*/feedback_publisher/**"
            ]
        );
        // Nodes of the other site have no policy here.
        assert!(allowed(&acl, "node wrist_tracker", "ingress", "put").is_empty());
    }

    #[test]
    fn the_peer_router_brings_only_crossing_topics_and_takes_no_hardware() {
        let acl = cfg(SiteName::Remote).zenoh_acl(&["lo".into()]);
        let mut inbound = allowed(&acl, "peer router local-router", "ingress", "put");
        inbound.sort();
        assert_eq!(
            inbound,
            [
                "*/teleop/hand/joint_targets/*/*",
                "*/teleop/operator_input/*/*",
                "*/teleop/remote_camera/receipts/*/*",
                "*/teleop/status/*/*",
                "*/teleop/wrist_pose/*/*",
            ]
        );
        let outbound = allowed(&acl, "peer router local-router", "egress", "put");
        assert!(outbound.contains(&"*/teleop/pr2/joint_states/*/*".to_owned()));
        assert!(!outbound.iter().any(|k| k.contains("hw/")), "{outbound:?}");
        assert!(!outbound.contains(&"*/teleop/wrist_pose/*/*".to_owned()));
        // Tokens: the other site's nodes in, this site's out.
        let tokens_in = allowed(
            &acl,
            "peer router local-router",
            "ingress",
            "liveliness_token",
        );
        assert!(tokens_in.iter().any(|k| k.ends_with("/wrist_tracker")));
        assert!(!tokens_in.iter().any(|k| k.ends_with("/pr2_arm_controller")));
        // The local router takes feedback in and sends commands out.
        let acl = cfg(SiteName::Local).zenoh_acl(&["lo".into()]);
        let inbound = allowed(&acl, "peer router remote-router", "ingress", "put");
        assert!(inbound.contains(&"*/teleop/shadow/fingertip_pressures/*/*".to_owned()));
        assert!(!inbound.contains(&"*/teleop/wrist_pose/*/*".to_owned()));
    }

    #[test]
    fn observers_watch_but_never_publish() {
        let acl = cfg(SiteName::Local).zenoh_acl(&["*".into()]);
        assert!(allowed(&acl, "observer teleop-observer", "ingress", "put").is_empty());
        assert_eq!(
            allowed(
                &acl,
                "observer teleop-observer",
                "ingress",
                "declare_subscriber"
            ),
            ["**", "@ros2_lv/**"]
        );
        let hw = acl["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["id"] == "observer teleop-observer hardware")
            .unwrap();
        assert!(hw.get("interfaces").is_none(), "`*` = any interface");
        // The admin space: observers may read it; no node, peer router or stranger.
        assert_eq!(
            allowed(&acl, "observer teleop-observer", "ingress", "query"),
            [ADMIN_SPACE]
        );
        for subject in ["node wrist_tracker", "peer router remote-router"] {
            assert!(
                allowed(&acl, subject, "ingress", "query").is_empty(),
                "{subject}"
            );
        }
    }

    #[test]
    fn names_are_checked() {
        cfg(SiteName::Local).validate().unwrap();
        let mut c = cfg(SiteName::Local);
        c.observers.push("wrist_tracker".into());
        let e = c.validate().unwrap_err();
        assert!(
            e.contains("wrist_tracker") && e.contains("observers"),
            "{e}"
        );
        let mut c = cfg(SiteName::Remote);
        c.peer_routers.push("a b".into());
        let e = c.validate().unwrap_err();
        assert!(e.contains("`a b`"), "{e}");
    }

    #[test]
    fn the_block_is_a_valid_zenoh_access_control() {
        for site in [SiteName::Local, SiteName::Remote] {
            let acl = cfg(site).zenoh_acl(&["lo".into()]);
            let mut z = zenoh::Config::default();
            z.insert_json5("access_control", &acl.to_string())
                .expect("zenoh takes the block");
        }
    }
}
