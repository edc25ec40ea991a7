"""The DDS set-up of a replay: a domain and a Fast DDS profile of its own."""

from __future__ import annotations

import os

from itasc_core.communication.dds import profile_file

__all__ = ['PROFILE', 'private_domain', 'select_profile']

#: The Fast DDS profile of a replay, whose one participant is alone in its domain: intra-process
#: delivery on, so that an event published in this process is at its readers when ``publish``
#: returns and an executor that finds nothing ready has nothing pending (the applications'
#: profile, :mod:`itasc_core.communication.dds`, turns it off); UDPv4 on 127.0.0.1 only.
PROFILE = """<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <library_settings><intraprocess_delivery>FULL</intraprocess_delivery></library_settings>
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>udp_localhost</transport_id>
        <type>UDPv4</type>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="itasc_replay" is_default_profile="true">
      <rtps>
        <useBuiltinTransports>false</useBuiltinTransports>
        <userTransports><transport_id>udp_localhost</transport_id></userTransports>
        <builtin>
          <metatrafficUnicastLocatorList><locator/></metatrafficUnicastLocatorList>
          <initialPeersList><locator><udpv4><address>127.0.0.1</address></udpv4></locator></initialPeersList>
        </builtin>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def private_domain() -> int:
    """A ROS domain id in 200..229, above those ROS tools and our tests use: a replay never joins
    a running application."""
    return 200 + os.getpid() % 30


def select_profile() -> None:
    """Point this process's Fast DDS at :data:`PROFILE` (before ``rclpy.init``)."""
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile_file(PROFILE, name='itasc_replay_fastdds'))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'  # rmw_fastrtps keeps the profile's transports
