-- Generated tile GLBs, so a restart does not regenerate them. `variant` names everything the bytes
-- depend on besides the coordinate (generator version, DEM fingerprint), so stale entries are
-- never served.
CREATE TABLE generated_tiles (
    z          INTEGER NOT NULL,
    x          INTEGER NOT NULL,
    y          INTEGER NOT NULL,
    variant    TEXT    NOT NULL,
    glb        BLOB    NOT NULL,
    created_at INTEGER NOT NULL,
    PRIMARY KEY (z, x, y, variant)
);
