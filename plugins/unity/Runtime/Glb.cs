// Glb.cs -- the GLB container (glTF 2.0 binary) and its accessors, nothing about anchors.
// Only data in the GLB's binary chunk is read (an external or data: URI buffer is refused).
using System;
using System.Collections.Generic;
using System.Text;

namespace Gsverse.MeshAnchor
{
    /// <summary>The asset breaks a rule an importer must enforce; the message says which.</summary>
    public sealed class AnchorRefusedException : Exception
    {
        public AnchorRefusedException(string message) : base(message) { }
    }

    public static class ComponentType
    {
        public const int Byte = 5120, UnsignedByte = 5121, Short = 5122, UnsignedShort = 5123,
                         UnsignedInt = 5125, Float = 5126;

        /// <summary>Bytes per component, or 0 for an unknown component type.</summary>
        public static int Size(int type)
        {
            switch (type)
            {
                case Byte: case UnsignedByte: return 1;
                case Short: case UnsignedShort: return 2;
                case UnsignedInt: case Float: return 4;
                default: return 0;
            }
        }
    }

    /// <summary>One accessor's elements where they lie in the binary chunk.</summary>
    public sealed class Accessor
    {
        public string Type;            // SCALAR, VEC2, ...
        public int ComponentType;
        public bool Normalized;
        public int Count, Components;
        internal byte[] Blob;
        internal int Start, Stride;

        uint Code(int i, int j)
        {
            int size = MeshAnchor.ComponentType.Size(ComponentType);
            int p = Start + i * Stride + j * size;
            uint v = 0;
            for (int b = size - 1; b >= 0; --b) v = (v << 8) | Blob[p + b];
            return v;
        }

        /// <summary>Component j of element i as a double, dequantized per glTF 2.0 §3.11:
        /// normalized unsigned c / (2^n - 1), normalized signed max(c / (2^(n-1) - 1), -1).</summary>
        public double Value(int i, int j)
        {
            uint raw = Code(i, j);
            switch (ComponentType)
            {
                case MeshAnchor.ComponentType.Float:
                    return BitConverter.ToSingle(BitConverter.GetBytes(raw), 0);
                case MeshAnchor.ComponentType.UnsignedInt: return raw;
                case MeshAnchor.ComponentType.Byte:
                {
                    int c = (int)(raw ^ 0x80u) - 0x80;
                    return Normalized ? Math.Max(c / 127.0, -1.0) : c;
                }
                case MeshAnchor.ComponentType.Short:
                {
                    int c = (int)(raw ^ 0x8000u) - 0x8000;
                    return Normalized ? Math.Max(c / 32767.0, -1.0) : c;
                }
                case MeshAnchor.ComponentType.UnsignedByte: return Normalized ? raw / 255.0 : raw;
                default: return Normalized ? raw / 65535.0 : raw;   // UNSIGNED_SHORT
            }
        }

        /// <summary>Every value as float32 (count * components), dequantized.</summary>
        public float[] Floats()
        {
            var out_ = new float[Count * Components];
            for (int i = 0; i < Count; ++i)
                for (int j = 0; j < Components; ++j) out_[i * Components + j] = (float)Value(i, j);
            return out_;
        }

        /// <summary>Component 0 of every element as an unsigned integer.</summary>
        public uint[] UInts()
        {
            var out_ = new uint[Count];
            for (int i = 0; i < Count; ++i) out_[i] = Code(i, 0);
            return out_;
        }
    }

    /// <summary>A parsed GLB: its JSON document and binary chunk.</summary>
    public sealed class Glb
    {
        public readonly Dictionary<string, object> Doc;
        public readonly byte[] Blob;

        static readonly Dictionary<string, int> TypeComponents = new Dictionary<string, int>
        {
            {"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}, {"MAT2", 4}, {"MAT3", 9}, {"MAT4", 16}
        };

        public static bool IsType(string type) { return type != null && TypeComponents.ContainsKey(type); }

        public Glb(byte[] data)
        {
            if (data.Length < 20 || data[0] != 'g' || data[1] != 'l' || data[2] != 'T' || data[3] != 'F')
                throw new AnchorRefusedException("not a GLB file");
            uint version = BitConverter.ToUInt32(data, 4), length = BitConverter.ToUInt32(data, 8);
            if (version != 2 || length != data.Length)
                throw new AnchorRefusedException("unsupported GLB version or wrong length");
            uint size = BitConverter.ToUInt32(data, 12), kind = BitConverter.ToUInt32(data, 16);
            if (kind != 0x4E4F534A || 20L + size > length)
                throw new AnchorRefusedException("GLB does not start with a complete JSON chunk");
            object doc;
            try
            {
                doc = Json.Parse(new UTF8Encoding(false, true).GetString(data, 20, (int)size));
            }
            catch (Exception e) when (e is FormatException || e is ArgumentException)
            {
                throw new AnchorRefusedException("invalid JSON chunk: " + e.Message);
            }
            Doc = doc as Dictionary<string, object>;
            if (Doc == null) throw new AnchorRefusedException("the JSON chunk is not an object");
            Blob = new byte[0];
            long pos = 20L + size;
            if (pos + 8 <= length)
            {
                uint bsize = BitConverter.ToUInt32(data, (int)pos), bkind = BitConverter.ToUInt32(data, (int)pos + 4);
                if (bkind == 0x004E4942)
                {
                    if (pos + 8 + bsize > length)
                        throw new AnchorRefusedException("BIN chunk runs past the end of the file");
                    Blob = new byte[bsize];
                    Array.Copy(data, pos + 8, Blob, 0, bsize);
                }
            }
        }

        // ---- JSON helpers

        public static Dictionary<string, object> Obj(object o) { return o as Dictionary<string, object>; }

        public static List<object> List(Dictionary<string, object> o, string key)
        {
            object v;
            return o != null && o.TryGetValue(key, out v) ? v as List<object> ?? new List<object>() : new List<object>();
        }

        public static object Get(Dictionary<string, object> o, string key)
        {
            object v;
            return o != null && o.TryGetValue(key, out v) ? v : null;
        }

        /// <summary>A JSON integer (a number with no fraction), or null.</summary>
        public static long? Int(object v)
        {
            if (!(v is double)) return null;
            double d = (double)v;
            if (d != Math.Floor(d) || Math.Abs(d) > 9007199254740992.0) return null;
            return (long)d;
        }

        public static long IntOr(Dictionary<string, object> o, string key, long fallback)
        {
            return Int(Get(o, key)) ?? fallback;
        }

        /// <summary>Element `index` of the top-level array `key`, refused when out of range.</summary>
        public Dictionary<string, object> Item(string key, object index, string what)
        {
            var items = List(Doc, key);
            long? i = Int(index);
            if (i == null || i < 0 || i >= items.Count)
                throw new AnchorRefusedException(what + ": " + key + " index " + (index ?? "null") + " out of range");
            return Obj(items[(int)i]) ?? new Dictionary<string, object>();
        }

        /// <summary>The accessor `index`, checked against its buffer view; refused when it is
        /// sparse, of another type than `types`, or does not fit.</summary>
        public Accessor Accessor(object index, string what, params string[] types)
        {
            var acc = Item("accessors", index, what);
            if (acc.ContainsKey("sparse")) throw new AnchorRefusedException(what + ": sparse accessors are not allowed here");
            string type = Get(acc, "type") as string;
            if (Array.IndexOf(types, type) < 0)
                throw new AnchorRefusedException(what + ": accessor type " + type + " (expected " + string.Join(" or ", types) + ")");
            int ctype = (int)IntOr(acc, "componentType", 0);
            int csize = ComponentType.Size(ctype);
            if (csize == 0) throw new AnchorRefusedException(what + ": unknown componentType " + ctype);
            bool normalized = Get(acc, "normalized") is bool && (bool)Get(acc, "normalized");
            if (normalized && (ctype == ComponentType.Float || ctype == ComponentType.UnsignedInt))
                throw new AnchorRefusedException(what + ": FLOAT and UNSIGNED_INT accessors cannot be normalized");
            if (!acc.ContainsKey("bufferView")) throw new AnchorRefusedException(what + ": accessor without bufferView");
            var view = Item("bufferViews", acc["bufferView"], what);
            var buffers = List(Doc, "buffers");
            if (IntOr(view, "buffer", 0) != 0 || (buffers.Count > 0 && Get(Obj(buffers[0]), "uri") != null))
                throw new AnchorRefusedException(what + ": only data in the GLB binary chunk is supported");
            int ncomp = TypeComponents[type];
            long elem = csize * ncomp;
            long stride = IntOr(view, "byteStride", elem), count = IntOr(acc, "count", 0);
            long offset = IntOr(acc, "byteOffset", 0);
            long vOff = IntOr(view, "byteOffset", 0), vLen = IntOr(view, "byteLength", 0);
            if (vOff < 0 || vLen < 0 || offset < 0 || count < 0 || vOff + vLen > Blob.Length)
                throw new AnchorRefusedException(what + ": bufferView runs past the end of the buffer");
            if (stride < elem || offset % csize != 0 || stride % csize != 0)
                throw new AnchorRefusedException(what + ": misaligned accessor or stride");
            if (count > 0 && offset + stride * (count - 1) + elem > vLen)
                throw new AnchorRefusedException(what + ": accessor runs past the end of its bufferView");
            return new Accessor
            {
                Type = type, ComponentType = ctype, Normalized = normalized, Count = (int)count,
                Components = ncomp, Blob = Blob, Start = (int)(vOff + offset), Stride = (int)stride
            };
        }
    }
}
