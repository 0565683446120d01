"""Bytes in, decoded MAVLink messages out: transports, pymavlink decoding, link statistics."""
