"""Write the rosbag2 (Jazzy, metadata version 9) YAML that ``rosbag2_storage_mcap`` expects.

References (ros2/rosbag2): ``rosbag2_storage/src/rosbag2_storage/qos.cpp`` (QoS profiles with
policy names as strings from version 9 on), ``rosbag2_storage/include/rosbag2_storage/yaml.hpp``
(the bag metadata) and ``rosbag2_storage_mcap/src/mcap_storage.cpp`` (channel metadata
``offered_qos_profiles`` and ``topic_type_hash``; a metadata record ``rosbag2`` whose key
``serialized_metadata`` holds the bag metadata).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import yaml

if TYPE_CHECKING:   # rclpy stays out of the writer process, which imports this module
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile

METADATA_VERSION = 9
STORAGE_IDENTIFIER = 'mcap'
ROS_DISTRO = 'jazzy'
INFINITE_NS = 2**63 - 1     # RMW_DURATION_INFINITE


def _time(duration: Duration) -> dict[str, int]:
    sec, nsec = divmod(duration.nanoseconds, 10**9)
    return {'sec': sec, 'nsec': nsec}


def qos_to_dict(profile: QoSProfile) -> dict[str, Any]:
    """Return a QoS profile in rosbag2's version-9 YAML form, field for field."""
    return {
        'history': profile.history.short_key,
        'depth': profile.depth,
        'reliability': profile.reliability.short_key,
        'durability': profile.durability.short_key,
        'deadline': _time(profile.deadline),
        'lifespan': _time(profile.lifespan),
        'liveliness': profile.liveliness.short_key,
        'liveliness_lease_duration': _time(profile.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions,
    }


def offered_qos(profile: QoSProfile) -> dict[str, Any]:
    """Return a publisher's profile as the ROS graph reports its offer, which rosbag2 records.

    The graph (``get_publishers_info_by_topic``) reports neither history nor depth, resolves
    system defaults (reliable, volatile, automatic) and reports unspecified durations as
    infinite; a recording made by rosbag2 of the same publisher holds exactly that.
    """
    from rclpy.duration import Infinite
    from rclpy.qos import QoSDurabilityPolicy, QoSLivelinessPolicy, QoSReliabilityPolicy

    def duration(value: Duration) -> Duration:
        return Infinite if value.nanoseconds in (0, INFINITE_NS) else value

    reliability = profile.reliability
    if reliability in (QoSReliabilityPolicy.SYSTEM_DEFAULT,
                       QoSReliabilityPolicy.BEST_AVAILABLE):
        reliability = QoSReliabilityPolicy.RELIABLE
    durability = profile.durability
    if durability == QoSDurabilityPolicy.SYSTEM_DEFAULT:
        durability = QoSDurabilityPolicy.VOLATILE
    elif durability == QoSDurabilityPolicy.BEST_AVAILABLE:
        durability = QoSDurabilityPolicy.TRANSIENT_LOCAL
    liveliness = profile.liveliness
    if liveliness in (QoSLivelinessPolicy.SYSTEM_DEFAULT, QoSLivelinessPolicy.BEST_AVAILABLE):
        liveliness = QoSLivelinessPolicy.AUTOMATIC
    return {
        'history': 'unknown',
        'depth': 0,
        'reliability': reliability.short_key,
        'durability': durability.short_key,
        'deadline': _time(duration(profile.deadline)),
        'lifespan': _time(duration(profile.lifespan)),
        'liveliness': liveliness.short_key,
        'liveliness_lease_duration': _time(duration(profile.liveliness_lease_duration)),
        'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions,
    }


def dump_yaml(data: Any) -> str:
    """Dump YAML in block style with keys in insertion order, without a trailing newline."""
    text: str = yaml.safe_dump(data, sort_keys=False, default_flow_style=False)
    return text.rstrip('\n')


def qos_profiles_yaml(profiles: Iterable[dict[str, Any]]) -> str:
    """Return the ``offered_qos_profiles`` channel metadata value (a YAML sequence)."""
    return dump_yaml(list(profiles))


@dataclass(frozen=True)
class TopicSummary:
    """One topic of a bag: what rosbag2 lists in ``topics_with_message_count``."""

    name: str
    type: str
    offered_qos_profiles: tuple[dict[str, Any], ...]
    type_description_hash: str
    message_count: int
    serialization_format: str = 'cdr'


def bag_metadata(file_name: str, topics: Sequence[TopicSummary], message_count: int,
                 start_ns: int | None, end_ns: int | None) -> dict[str, Any]:
    """Return rosbag2's bag metadata (version 9) of a single-file MCAP bag."""
    if start_ns is None or end_ns is None:
        starting, duration = 2**63 - 1, 0   # what rosbag2 writes for a bag without messages
    else:
        starting, duration = start_ns, end_ns - start_ns
    return {
        'version': METADATA_VERSION,
        'storage_identifier': STORAGE_IDENTIFIER,
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': starting},
        'message_count': message_count,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': topic.name,
                    'type': topic.type,
                    'serialization_format': topic.serialization_format,
                    'offered_qos_profiles': list(topic.offered_qos_profiles),
                    'type_description_hash': topic.type_description_hash,
                },
                'message_count': topic.message_count,
            }
            for topic in topics
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{
            'path': file_name,
            'starting_time': {'nanoseconds_since_epoch': starting},
            'duration': {'nanoseconds': duration},
            'message_count': message_count,
        }],
        'custom_data': None,
        'ros_distro': ROS_DISTRO,
    }
