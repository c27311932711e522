#pragma once
// The GenICam XML of the simulated camera (tests/drivers/gentl_sim/gentl_sim.cpp),
// and the register map it describes. All registers are little endian;
// integers 4 bytes, floats 8 bytes. The XML itself sits in the register
// space at kXmlAddress, reached through a "Local:" URL as on a real device.

#include <cstdint>

namespace lifmcr::gentl_sim {

enum : std::uint64_t {
  kVendorName = 0x0000,  // 64-byte strings
  kModelName = 0x0040,
  kSerialNumber = 0x0080,
  kWidth = 0x0100,
  kHeight = 0x0104,
  kOffsetX = 0x0108,
  kOffsetY = 0x010C,
  kSensorWidth = 0x0110,  // read-only
  kSensorHeight = 0x0114,
  kPixelFormat = 0x0118,
  kPayloadSize = 0x011C,  // read-only, computed
  kAcquisitionMode = 0x0200,
  kAcquisitionStart = 0x0204,   // write 1
  kAcquisitionStop = 0x0208,    // write 1
  kFrameRate = 0x0210,          // float, free-run rate in Hz
  kTriggerSelector = 0x0300,    // 0 FrameStart, 1 AcquisitionStart
  kTriggerMode = 0x0310,        // + 4 * selector: 0 Off, 1 On
  kTriggerSource = 0x0320,      // + 4 * selector: 0 Software, 1 Line0, 2 Line1
  kTriggerActivation = 0x0330,  // + 4 * selector: 0 RisingEdge, 1 FallingEdge
  kTriggerSoftware = 0x0340,    // write 1
  kExposureTime = 0x0400,       // float, us
  kGain = 0x0408,               // float, dB
  kDropEvery = 0x0500,          // every Nth frame id is lost in transport (0 = none)
  kIncompleteEvery = 0x0504,    // every Nth frame is delivered incomplete (0 = none)
  kLinePeriodUs = 0x0508,       // period of the "hardware" pulses on Line0/Line1
  kLastFrameId = 0x050C,        // read-only: the last frame id the camera used
  kChunkModeActive = 0x0520,    // 1: each frame carries the chunk kChunkId after the image
  kChunkSelector = 0x0524,      // 0 Timestamp, 1 FrameID
  kChunkEnable = 0x0528,        // + 4 * selector
  kTimestampLatch = 0x0530,     // write 1: the device clock (ns) into kTimestampLatchValue
  kTimestampLatchValue = 0x0538,  // 8 bytes, read-only
  kXmlAddress = 0x10000,
};
// The chunk: [trigger time, ns, u64 LE][frame id, u64 LE], after the image.
inline constexpr std::uint64_t kChunkId = 0x4C494643;
inline constexpr std::uint64_t kChunkBytes = 16;

inline constexpr char kXml[] = R"XML(<?xml version="1.0" encoding="utf-8"?>
<RegisterDescription ModelName="GenTlSim" VendorName="lifmcr" ToolTip="lifmcr GenTL test camera"
  StandardNameSpace="None" SchemaMajorVersion="1" SchemaMinorVersion="1" SchemaSubMinorVersion="0"
  MajorVersion="1" MinorVersion="0" SubMinorVersion="0"
  ProductGuid="6f1d2a60-1c3e-4d8e-9a57-1f0d6b7e2a10" VersionGuid="0b8c7d52-3e4f-4a61-8b2d-9c0e1f2a3b40"
  xmlns="http://www.genicam.org/GenApi/Version_1_1">
  <Category Name="Root" NameSpace="Standard">
    <pFeature>DeviceControl</pFeature>
    <pFeature>ImageFormatControl</pFeature>
    <pFeature>AcquisitionControl</pFeature>
    <pFeature>AnalogControl</pFeature>
    <pFeature>SimulationControl</pFeature>
    <pFeature>ChunkDataControl</pFeature>
  </Category>
  <Category Name="ChunkDataControl" NameSpace="Standard">
    <pFeature>ChunkModeActive</pFeature>
    <pFeature>ChunkSelector</pFeature>
    <pFeature>ChunkEnable</pFeature>
    <pFeature>ChunkTimestamp</pFeature>
    <pFeature>ChunkFrameID</pFeature>
  </Category>
  <Category Name="DeviceControl" NameSpace="Standard">
    <pFeature>DeviceVendorName</pFeature>
    <pFeature>DeviceModelName</pFeature>
    <pFeature>DeviceSerialNumber</pFeature>
    <pFeature>TimestampLatch</pFeature>
    <pFeature>TimestampLatchValue</pFeature>
  </Category>
  <Category Name="ImageFormatControl" NameSpace="Standard">
    <pFeature>SensorWidth</pFeature>
    <pFeature>SensorHeight</pFeature>
    <pFeature>Width</pFeature>
    <pFeature>Height</pFeature>
    <pFeature>OffsetX</pFeature>
    <pFeature>OffsetY</pFeature>
    <pFeature>PixelFormat</pFeature>
    <pFeature>PayloadSize</pFeature>
  </Category>
  <Category Name="AcquisitionControl" NameSpace="Standard">
    <pFeature>AcquisitionMode</pFeature>
    <pFeature>AcquisitionStart</pFeature>
    <pFeature>AcquisitionStop</pFeature>
    <pFeature>AcquisitionFrameRate</pFeature>
    <pFeature>TriggerSelector</pFeature>
    <pFeature>TriggerMode</pFeature>
    <pFeature>TriggerSource</pFeature>
    <pFeature>TriggerActivation</pFeature>
    <pFeature>TriggerSoftware</pFeature>
    <pFeature>ExposureTime</pFeature>
  </Category>
  <Category Name="AnalogControl" NameSpace="Standard">
    <pFeature>Gain</pFeature>
  </Category>
  <Category Name="SimulationControl" NameSpace="Custom">
    <pFeature>SimDropEvery</pFeature>
    <pFeature>SimIncompleteEvery</pFeature>
    <pFeature>SimLinePeriodUs</pFeature>
    <pFeature>SimLastFrameId</pFeature>
  </Category>

  <StringReg Name="DeviceVendorName" NameSpace="Standard">
    <Address>0x0000</Address><Length>64</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
  </StringReg>
  <StringReg Name="DeviceModelName" NameSpace="Standard">
    <Address>0x0040</Address><Length>64</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
  </StringReg>
  <StringReg Name="DeviceSerialNumber" NameSpace="Standard">
    <Address>0x0080</Address><Length>64</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
  </StringReg>

  <Integer Name="SensorWidth" NameSpace="Standard"><pValue>SensorWidthReg</pValue></Integer>
  <IntReg Name="SensorWidthReg">
    <Address>0x0110</Address><Length>4</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="SensorHeight" NameSpace="Standard"><pValue>SensorHeightReg</pValue></Integer>
  <IntReg Name="SensorHeightReg">
    <Address>0x0114</Address><Length>4</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="Width" NameSpace="Standard">
    <pValue>WidthReg</pValue><Min>1</Min><pMax>SensorWidthReg</pMax><Inc>1</Inc>
  </Integer>
  <IntReg Name="WidthReg">
    <Address>0x0100</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="Height" NameSpace="Standard">
    <pValue>HeightReg</pValue><Min>1</Min><pMax>SensorHeightReg</pMax><Inc>1</Inc>
  </Integer>
  <IntReg Name="HeightReg">
    <Address>0x0104</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="OffsetX" NameSpace="Standard">
    <pValue>OffsetXReg</pValue><Min>0</Min><pMax>SensorWidthReg</pMax><Inc>1</Inc>
  </Integer>
  <IntReg Name="OffsetXReg">
    <Address>0x0108</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="OffsetY" NameSpace="Standard">
    <pValue>OffsetYReg</pValue><Min>0</Min><pMax>SensorHeightReg</pMax><Inc>1</Inc>
  </Integer>
  <IntReg Name="OffsetYReg">
    <Address>0x010C</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Enumeration Name="PixelFormat" NameSpace="Standard">
    <EnumEntry Name="Mono8"><Value>0x01080001</Value></EnumEntry>
    <EnumEntry Name="BayerGR8"><Value>0x01080008</Value></EnumEntry>
    <EnumEntry Name="BayerRG8"><Value>0x01080009</Value></EnumEntry>
    <EnumEntry Name="BayerGB8"><Value>0x0108000A</Value></EnumEntry>
    <EnumEntry Name="BayerBG8"><Value>0x0108000B</Value></EnumEntry>
    <EnumEntry Name="BGR8"><Value>0x02180015</Value></EnumEntry>
    <pValue>PixelFormatReg</pValue>
  </Enumeration>
  <IntReg Name="PixelFormatReg">
    <Address>0x0118</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="PayloadSize" NameSpace="Standard"><pValue>PayloadSizeReg</pValue></Integer>
  <IntReg Name="PayloadSizeReg">
    <Address>0x011C</Address><Length>4</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>

  <Enumeration Name="AcquisitionMode" NameSpace="Standard">
    <EnumEntry Name="Continuous"><Value>0</Value></EnumEntry>
    <EnumEntry Name="SingleFrame"><Value>1</Value></EnumEntry>
    <pValue>AcquisitionModeReg</pValue>
  </Enumeration>
  <IntReg Name="AcquisitionModeReg">
    <Address>0x0200</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Command Name="AcquisitionStart" NameSpace="Standard">
    <pValue>AcquisitionStartReg</pValue><CommandValue>1</CommandValue>
  </Command>
  <IntReg Name="AcquisitionStartReg">
    <Address>0x0204</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Command Name="AcquisitionStop" NameSpace="Standard">
    <pValue>AcquisitionStopReg</pValue><CommandValue>1</CommandValue>
  </Command>
  <IntReg Name="AcquisitionStopReg">
    <Address>0x0208</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Float Name="AcquisitionFrameRate" NameSpace="Standard">
    <pValue>AcquisitionFrameRateReg</pValue><Min>0.1</Min><Max>1000</Max><Unit>Hz</Unit>
  </Float>
  <FloatReg Name="AcquisitionFrameRateReg">
    <Address>0x0210</Address><Length>8</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Endianess>LittleEndian</Endianess>
  </FloatReg>

  <Enumeration Name="TriggerSelector" NameSpace="Standard">
    <EnumEntry Name="FrameStart"><Value>0</Value></EnumEntry>
    <EnumEntry Name="AcquisitionStart"><Value>1</Value></EnumEntry>
    <pValue>TriggerSelectorReg</pValue>
    <pSelected>TriggerMode</pSelected>
    <pSelected>TriggerSource</pSelected>
    <pSelected>TriggerActivation</pSelected>
  </Enumeration>
  <IntReg Name="TriggerSelectorReg">
    <Address>0x0300</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Enumeration Name="TriggerMode" NameSpace="Standard">
    <EnumEntry Name="Off"><Value>0</Value></EnumEntry>
    <EnumEntry Name="On"><Value>1</Value></EnumEntry>
    <pValue>TriggerModeReg</pValue>
  </Enumeration>
  <IntReg Name="TriggerModeReg">
    <Address>0x0310</Address><pIndex Offset="4">TriggerSelectorReg</pIndex>
    <Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Enumeration Name="TriggerSource" NameSpace="Standard">
    <EnumEntry Name="Software"><Value>0</Value></EnumEntry>
    <EnumEntry Name="Line0"><Value>1</Value></EnumEntry>
    <EnumEntry Name="Line1"><Value>2</Value></EnumEntry>
    <pValue>TriggerSourceReg</pValue>
  </Enumeration>
  <IntReg Name="TriggerSourceReg">
    <Address>0x0320</Address><pIndex Offset="4">TriggerSelectorReg</pIndex>
    <Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Enumeration Name="TriggerActivation" NameSpace="Standard">
    <EnumEntry Name="RisingEdge"><Value>0</Value></EnumEntry>
    <EnumEntry Name="FallingEdge"><Value>1</Value></EnumEntry>
    <pValue>TriggerActivationReg</pValue>
  </Enumeration>
  <IntReg Name="TriggerActivationReg">
    <Address>0x0330</Address><pIndex Offset="4">TriggerSelectorReg</pIndex>
    <Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Command Name="TriggerSoftware" NameSpace="Standard">
    <pValue>TriggerSoftwareReg</pValue><CommandValue>1</CommandValue>
  </Command>
  <IntReg Name="TriggerSoftwareReg">
    <Address>0x0340</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Float Name="ExposureTime" NameSpace="Standard">
    <pValue>ExposureTimeReg</pValue><Min>1</Min><Max>10000000</Max><Unit>us</Unit>
  </Float>
  <FloatReg Name="ExposureTimeReg">
    <Address>0x0400</Address><Length>8</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Endianess>LittleEndian</Endianess>
  </FloatReg>
  <Float Name="Gain" NameSpace="Standard">
    <pValue>GainReg</pValue><Min>0</Min><Max>48</Max><Unit>dB</Unit>
  </Float>
  <FloatReg Name="GainReg">
    <Address>0x0408</Address><Length>8</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Endianess>LittleEndian</Endianess>
  </FloatReg>

  <Integer Name="SimDropEvery" NameSpace="Custom"><pValue>SimDropEveryReg</pValue></Integer>
  <IntReg Name="SimDropEveryReg">
    <Address>0x0500</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="SimIncompleteEvery" NameSpace="Custom"><pValue>SimIncompleteEveryReg</pValue></Integer>
  <IntReg Name="SimIncompleteEveryReg">
    <Address>0x0504</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="SimLinePeriodUs" NameSpace="Custom"><pValue>SimLinePeriodUsReg</pValue></Integer>
  <IntReg Name="SimLinePeriodUsReg">
    <Address>0x0508</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>

  <Integer Name="SimLastFrameId" NameSpace="Custom"><pValue>SimLastFrameIdReg</pValue></Integer>
  <IntReg Name="SimLastFrameIdReg">
    <Address>0x050C</Address><Length>4</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Boolean Name="ChunkModeActive" NameSpace="Standard">
    <pValue>ChunkModeActiveReg</pValue><OnValue>1</OnValue><OffValue>0</OffValue>
  </Boolean>
  <IntReg Name="ChunkModeActiveReg">
    <Address>0x0520</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Enumeration Name="ChunkSelector" NameSpace="Standard">
    <EnumEntry Name="Timestamp"><Value>0</Value></EnumEntry>
    <EnumEntry Name="FrameID"><Value>1</Value></EnumEntry>
    <pValue>ChunkSelectorReg</pValue>
    <pSelected>ChunkEnable</pSelected>
  </Enumeration>
  <IntReg Name="ChunkSelectorReg">
    <Address>0x0524</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Boolean Name="ChunkEnable" NameSpace="Standard">
    <pValue>ChunkEnableReg</pValue><OnValue>1</OnValue><OffValue>0</OffValue>
  </Boolean>
  <IntReg Name="ChunkEnableReg">
    <Address>0x0528</Address><pIndex Offset="4">ChunkSelectorReg</pIndex>
    <Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="ChunkTimestamp" NameSpace="Standard"><pValue>ChunkTimestampReg</pValue></Integer>
  <IntReg Name="ChunkTimestampReg">
    <Address>0x0</Address><Length>8</Length><AccessMode>RO</AccessMode><pPort>ChunkPortLifmcr</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="ChunkFrameID" NameSpace="Standard"><pValue>ChunkFrameIDReg</pValue></Integer>
  <IntReg Name="ChunkFrameIDReg">
    <Address>0x8</Address><Length>8</Length><AccessMode>RO</AccessMode><pPort>ChunkPortLifmcr</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Port Name="ChunkPortLifmcr" NameSpace="Custom"><ChunkID>4C494643</ChunkID></Port>
  <Command Name="TimestampLatch" NameSpace="Standard">
    <pValue>TimestampLatchReg</pValue><CommandValue>1</CommandValue>
  </Command>
  <IntReg Name="TimestampLatchReg">
    <Address>0x0530</Address><Length>4</Length><AccessMode>RW</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>
  <Integer Name="TimestampLatchValue" NameSpace="Standard"><pValue>TimestampLatchValueReg</pValue></Integer>
  <IntReg Name="TimestampLatchValueReg">
    <Address>0x0538</Address><Length>8</Length><AccessMode>RO</AccessMode><pPort>Device</pPort>
    <Sign>Unsigned</Sign><Endianess>LittleEndian</Endianess>
  </IntReg>

  <Port Name="Device" NameSpace="Standard"/>
</RegisterDescription>
)XML";

}  // namespace lifmcr::gentl_sim
