//! The table of contents shared by the log and param subsystems (TOC v2 of
//! the firmware's `log.c`/`param.c`, cflib's `toc.py`): `CMD_TOC_INFO_V2`
//! answers the entry count (u16) and a CRC (u32), `CMD_TOC_ITEM_V2` one
//! entry by its 16-bit id: the type byte, then `group\0name\0`.
//!
//! cflib caches a TOC under its CRC (`toccache.py`), so the CRC must change
//! whenever the table does. The firmware takes a CRC over its in-memory
//! tables (addresses included), which has no meaning outside one build;
//! here it is the CRC-32 (IEEE, as the firmware's `crc32.c`) of every
//! entry's type byte, group and name with their NUL terminators, in id
//! order: the same table always gives the same CRC, another table another.

/// `CMD_TOC_ITEM_V2` and `CMD_TOC_INFO_V2` (cflib `toc.py`).
pub const CMD_TOC_ITEM_V2: u8 = 2;
pub const CMD_TOC_INFO_V2: u8 = 3;

/// One entry: its type byte (with the access bits) and its names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TocEntry {
    pub ty: u8,
    pub group: &'static str,
    pub name: &'static str,
}

impl TocEntry {
    fn item_bytes(&self) -> Vec<u8> {
        let mut v = vec![self.ty];
        v.extend_from_slice(self.group.as_bytes());
        v.push(0);
        v.extend_from_slice(self.name.as_bytes());
        v.push(0);
        v
    }
}

pub fn crc(entries: &[TocEntry]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    for e in entries {
        h.update(&e.item_bytes());
    }
    h.finalize()
}

/// The answer to a TOC channel request (`None`: the firmware answers
/// nothing, e.g. an id beyond the table or an unknown command).
/// `info_tail` follows the count and CRC in the info answer (the log's
/// block and operation limits; nothing for params).
pub fn answer(entries: &[TocEntry], request: &[u8], info_tail: &[u8]) -> Option<Vec<u8>> {
    match *request.first()? {
        CMD_TOC_INFO_V2 => {
            let mut v = vec![CMD_TOC_INFO_V2];
            v.extend_from_slice(&(entries.len() as u16).to_le_bytes());
            v.extend_from_slice(&crc(entries).to_le_bytes());
            v.extend_from_slice(info_tail);
            Some(v)
        }
        CMD_TOC_ITEM_V2 => {
            let id = super::packet::u16_at(request, 1)?;
            let e = entries.get(id as usize)?;
            let mut v = vec![CMD_TOC_ITEM_V2];
            v.extend_from_slice(&id.to_le_bytes());
            v.extend(e.item_bytes());
            v.truncate(super::packet::MAX_DATA);
            Some(v)
        }
        _ => None,
    }
}

/// The id of `group.name`.
pub fn find(entries: &[TocEntry], full: &str) -> Option<u16> {
    let (g, n) = full.split_once('.')?;
    entries
        .iter()
        .position(|e| e.group == g && e.name == n)
        .map(|i| i as u16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn info_and_items_follow_toc_v2() {
        let t = [
            TocEntry {
                ty: 7,
                group: "pm",
                name: "vbat",
            },
            TocEntry {
                ty: 1,
                group: "pm",
                name: "state",
            },
        ];
        let info = answer(&t, &[3], &[16, 128]).unwrap();
        assert_eq!(&info[..3], &[3, 2, 0]);
        assert_eq!(u32::from_le_bytes(info[3..7].try_into().unwrap()), crc(&t));
        assert_eq!(&info[7..], &[16, 128]);
        assert_eq!(
            answer(&t, &[2, 1, 0], &[]).unwrap(),
            b"\x02\x01\x00\x01pm\0state\0".to_vec()
        );
        assert_eq!(answer(&t, &[2, 2, 0], &[]), None);
        assert_eq!(answer(&t, &[2, 1], &[]), None);
        assert_eq!(find(&t, "pm.state"), Some(1));
        // Another table, another CRC (cflib's cache key).
        assert_ne!(crc(&t), crc(&t[..1]));
    }
}
