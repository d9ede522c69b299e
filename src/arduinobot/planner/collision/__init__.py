"""The collision layer: OBB trees and their bounds (obbtree, advance), the collision
world (world), the allowed-collision matrix (acm, acm_gen, acm_proof), and motions
proven free between samples (certify, body_speed, motion_check)."""
