"""rmw_zenoh's wire: what a ROS 2 entity is on Zenoh.

- ``types``: the ROS 2 message types, their CDR and type hashes (rosbags).
- ``qos``: QoS profiles as rmw_zenoh encodes them.
- ``names``: ROS names mangled into Zenoh keys.
- ``graph``: the liveliness tokens that make the ROS graph.
- ``topics``: publishers and subscriptions.
- ``services``: service servers and clients.
- ``node``: a node and its entities.
"""
