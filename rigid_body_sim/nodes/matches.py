"""Which publishers a recorder has matched: the recorder's report and the simulator's
reading of it before a lockstep run's t = 0.

Why. A lockstep controller keeps its commands for late joiners (transient local), and the
recorder subscribes for that history once it has discovered the controller. The recorder
and the controller discover each other in a pair the simulator cannot see: a run as fast
as possible lasts a fraction of a second, and its controller could be stopped, with its
history, before the recorder had matched it (the bag then held no command, 1 lockstep
run in ~10 of ``make test``). So the recorder says what it has matched, and the simulator
starts only once each recorder has matched the controllers of the command topics it
records.

The report, ``<recorder>/matched_publishers`` (std_msgs/String, reliable, transient
local, published at each change), is JSON ``{"matched": {topic: [publisher node, ...]},
"all": bool, "exclude": [topic, ...]}``: what the recorder records (each wanted topic; with
``all`` any other but the excluded and hidden ones) and, per topic, every publisher
discovered on it once its subscription has matched them all (none before it is
subscribed, while some publisher is not matched yet, or while a transient-local one waits
for the subscription that gets its history).
"""
import json

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

TOPIC = '~/matched_publishers'
SUFFIX = '/matched_publishers'
PERIOD_S = 0.05  # how often the recorder looks at its matches (graph queries, ~µs each)
# ... and once they have not changed for SETTLE_S. Each look wakes the recorder's executor,
# and a wake-up of rclpy's Python executor costs ~1 ms (it rebuilds its wait set over every
# subscription, service and event handler): at 20 Hz that was 60% of an idle recorder's CPU
# (0.043 -> 0.016 CPU-s per s without it, issue 32). A change seen at a quiet look (a new
# publisher matched) goes out at once and the looks are fast again; a new subscription
# makes them fast too.
QUIET_PERIOD_S = 0.25
SETTLE_S = 1.0


def _qos():
    return QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def fqn(namespace: str, name: str) -> str:
    """A node's fully qualified name (the graph may give its namespace without a '/')."""
    return f'/{namespace.strip("/")}/{name}'.replace('//', '/')


def hidden(topic: str) -> bool:
    """A hidden topic (a part starts with '_'): ``all`` leaves it out."""
    return any(part.startswith('_') for part in topic.split('/'))


def latched(publishers) -> bool:
    """Every publisher (of a non-empty list) offers transient-local durability."""
    return bool(publishers) and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                    for p in publishers)


class Report:
    """The recorder's side: ``update`` publishes the report when it changed."""

    def __init__(self, node):
        self.node = node
        self.pub = node.create_publisher(String, TOPIC, _qos())
        self.last = None

    def update(self, subs, wanted, early, all_topics: bool, exclude) -> bool:
        """``subs``: {topic: subscription}; ``wanted``: the topics it records by name (not
        excluded or skipped); ``early``: those subscribed before a publisher was seen.
        True if the report changed (and was published)."""
        get = self.node.get_publishers_info_by_topic
        matched = dict.fromkeys(wanted, [])
        for topic, sub in subs.items():
            publishers = get(topic)
            waits = topic in early and latched(publishers)  # for its history
            complete = sub.get_publisher_count() >= len(publishers)
            matched[topic] = [] if waits or not complete else sorted(
                {fqn(p.node_namespace, p.node_name) for p in publishers})
        report = {'matched': matched, 'all': all_topics, 'exclude': sorted(exclude)}
        if report == self.last:
            return False
        self.last = report
        self.pub.publish(String(data=json.dumps(report, sort_keys=True)))
        return True


class Reports:
    """The simulator's side: every recorder's report, read until ``close``."""

    def __init__(self, node):
        self.node = node
        self.entries = {}  # report topic -> {'sub': subscription, 'report': dict | None}

    def unmatched(self, subs) -> list:
        """Of the command subscriptions ``subs``, the topics a recorder records whose
        publishers (this node's view of them: the controllers) it has not all matched yet,
        and the reports not received yet."""
        node = self.node
        for topic, _ in node.get_topic_names_and_types():
            if topic.endswith(SUFFIX) and topic not in self.entries:
                entry = self.entries[topic] = {'report': None}
                entry['sub'] = node.create_subscription(
                    String, topic, lambda m, e=entry: e.update(report=json.loads(m.data)),
                    _qos())
        out = [topic for topic, e in self.entries.items() if e['report'] is None]
        for sub in subs:
            name = sub.topic_name
            controllers = {fqn(p.node_namespace, p.node_name)
                           for p in node.get_publishers_info_by_topic(name)}
            for topic, entry in self.entries.items():
                report = entry['report']
                if report is None:
                    continue
                matched = report['matched']
                records = name in matched or (report['all'] and not hidden(name)
                                              and name not in report['exclude'])
                if records and not controllers <= set(matched.get(name, [])):
                    out.append(f'{name} (by {topic[:-len(SUFFIX)]})')
        return out

    def close(self):
        for entry in self.entries.values():
            self.node.destroy_subscription(entry['sub'])
        self.entries = {}
