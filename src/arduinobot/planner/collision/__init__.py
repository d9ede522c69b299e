"""The collision layer: OBB trees and their bounds (obbtree, advance), the collision
world (world), a point cloud's cells as one body (cloud_body), the allowed-collision matrix (acm, acm_gen, acm_proof), and motions
proven free between samples (certify, body_speed, motion_check)."""
